"""robo_comp.tui."""

"""robo_comp.plugins."""

"""robo_comp.wall."""

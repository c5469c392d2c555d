"""robo_comp.core."""

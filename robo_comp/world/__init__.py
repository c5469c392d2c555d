"""robo_comp.world."""

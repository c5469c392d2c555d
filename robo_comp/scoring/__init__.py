"""robo_comp.scoring."""

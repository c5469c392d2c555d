"""robo_comp.teams."""

"""robo_comp.wall: the pygame display wall (live or replayed match, one screen or tiles); see docs/wall.md."""

"""The match with no sockets: what is true in the world and what follows from it.

Modules here are plain Python on plain data (no ZeroMQ, no processes), so that the core, the robot
hosts and the bench can all ask them the same questions:

- :mod:`~robo_comp.match.plausibility`: which reported poses a robot could have reached (the
  fair-play check that keeps teleports, wall-walking and out-of-arena poses out of the match).
"""

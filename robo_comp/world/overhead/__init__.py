"""A real positioning system: overhead cameras that see fiducial markers on the robots.

The thesis's Hexamite positioning never worked (sections 7.6, 9.2); the standard answer today
is Duckietown's and Robotarium's: cameras above the arena and a marker on every robot.

- :mod:`~robo_comp.world.overhead.markers`: the ArUco dictionary, marker images, a printable sheet;
- :mod:`~robo_comp.world.overhead.binding`: which marker is which robot (the organiser's file) and
  which floor markers sit at which cells, checked;
- :mod:`~robo_comp.world.overhead.calibrate`: floor markers → the image-to-cell homography, its
  reprojection error, a moved camera noticed; checkerboard views → intrinsics;
- :mod:`~robo_comp.world.overhead.detect`: frames → marker corners → robot poses (x, y, heading);
- :mod:`~robo_comp.world.overhead.fuse`: several cameras → one pose per robot;
- :mod:`~robo_comp.world.overhead.synth`: synthetic overhead frames of a simulated arena (perspective,
  blur, noise, uneven light, occlusion) with the true poses known, for tests and benches;
- :mod:`~robo_comp.world.overhead.source`: the ``robo-comp camera`` process: frames in, fixes out on
  a ZeroMQ PUB socket that robot hosts subscribe to (``robo-comp robots --positioning camera:URL``).

OpenCV is imported by the modules that need it, not by this package.
"""

"""ROS 2 robots over DDS without ROS installed (Cyclone DDS from PyPI; ``pip install 'robo_comp[ros2]'``).

:mod:`~robo_comp.robots.ros2.msgs` holds the ROS 2 message types, :mod:`~robo_comp.robots.ros2.bus`
the DDS participant, topic names and QoS, :mod:`~robo_comp.robots.ros2.driver` the driver the
robot host uses (``robo-comp robots --driver ros2``), :mod:`~robo_comp.robots.ros2.simrobot`
a simulated ROS 2 robot to test it against.
"""

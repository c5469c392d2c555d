"""The ROS 2 messages the driver speaks, as Cyclone DDS IDL dataclasses with ROS 2's own names.

A ROS 2 message type ``pkg/msg/Name`` travels over DDS as the IDL struct
``pkg::msg::dds_::Name_``; its topic ``/ns/name`` is the DDS topic ``rt/ns/name``
(see :func:`robo_comp.robots.ros2.bus.topic_name`). The field order and types below are those
of the ``.msg`` files of ROS 2 (Humble and later), so a robot running any ROS 2 middleware
that speaks RTPS with XCDR1 plain types (``rmw_cyclonedds_cpp``, ``rmw_fastrtps_cpp``) reads
and writes the same bytes. Only what the driver needs is here: ``Twist`` (commands),
``Odometry`` (odometry) and ``LaserScan`` (range).

No ``from __future__ import annotations`` here: Cyclone DDS reads the annotations as types.
Its ``array[T, n]`` and ``sequence[T]`` are runtime descriptions of IDL types, which its type
hints do not declare generic: the fields that use them carry a coded ``type: ignore``.
"""

from dataclasses import dataclass, field

from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, float32, float64, int32, sequence, uint32


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    """``builtin_interfaces/Time``."""

    sec: int32 = 0
    nanosec: uint32 = 0


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    """``std_msgs/Header``."""

    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    """``geometry_msgs/Vector3``."""

    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    """``geometry_msgs/Twist``: ``linear.x`` m/s forward, ``angular.z`` rad/s counter-clockwise."""

    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    """``geometry_msgs/Point``."""

    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    """``geometry_msgs/Quaternion``."""

    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    w: float64 = 1.0


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    """``geometry_msgs/Pose``."""

    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)


@dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    """``geometry_msgs/PoseWithCovariance``."""

    pose: Pose = field(default_factory=Pose)
    covariance: array[float64, 36] = field(default_factory=lambda: [0.0] * 36)  # type: ignore[type-arg, valid-type, assignment]  # cyclonedds IDL type


@dataclass
class TwistWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::TwistWithCovariance_"):
    """``geometry_msgs/TwistWithCovariance``."""

    twist: Twist = field(default_factory=Twist)
    covariance: array[float64, 36] = field(default_factory=lambda: [0.0] * 36)  # type: ignore[type-arg, valid-type, assignment]  # cyclonedds IDL type


@dataclass
class Odometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    """``nav_msgs/Odometry``: the pose in the ``odom`` frame (x forward at the start, y left)."""

    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    pose: PoseWithCovariance = field(default_factory=PoseWithCovariance)
    twist: TwistWithCovariance = field(default_factory=TwistWithCovariance)


@dataclass
class LaserScan(IdlStruct, typename="sensor_msgs::msg::dds_::LaserScan_"):
    """``sensor_msgs/LaserScan``: ranges in metres from ``angle_min`` counter-clockwise
    (0 = straight ahead)."""

    header: Header = field(default_factory=Header)
    angle_min: float32 = 0.0
    angle_max: float32 = 0.0
    angle_increment: float32 = 0.0
    time_increment: float32 = 0.0
    scan_time: float32 = 0.0
    range_min: float32 = 0.0
    range_max: float32 = 0.0
    ranges: sequence[float32] = field(default_factory=list)  # type: ignore[type-arg, assignment]  # cyclonedds IDL type
    intensities: sequence[float32] = field(default_factory=list)  # type: ignore[type-arg, assignment]  # cyclonedds IDL type


def stamp(t: float) -> Time:
    """A ROS 2 time stamp for ``t`` seconds."""
    sec = int(t)
    return Time(sec=sec, nanosec=int((t - sec) * 1e9))


def yaw_of(q: Quaternion) -> float:
    """The yaw (radians, counter-clockwise) of a rotation about z."""
    import math

    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def quaternion_of(yaw: float) -> Quaternion:
    """The rotation by ``yaw`` radians about z."""
    import math

    return Quaternion(z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0))

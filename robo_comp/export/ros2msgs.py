"""ROS 2 message definitions (``.msg`` text with its dependencies, as ``ros2 bag`` stores them in
an MCAP schema) of the messages the MCAP export writes."""
from __future__ import annotations

_SEP = "=" * 80 + "\n"

_DEFS = {
    "builtin_interfaces/Time": "int32 sec\nuint32 nanosec\n",
    "std_msgs/Header": "builtin_interfaces/Time stamp\nstring frame_id\n",
    "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    "geometry_msgs/Pose": "Point position\nQuaternion orientation\n",
    "geometry_msgs/PoseStamped": "std_msgs/Header header\nPose pose\n",
    "geometry_msgs/PointStamped": "std_msgs/Header header\nPoint point\n",
    "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/Transform": "Vector3 translation\nQuaternion rotation\n",
    "geometry_msgs/TransformStamped": "std_msgs/Header header\nstring child_frame_id\nTransform transform\n",
    "tf2_msgs/TFMessage": "geometry_msgs/TransformStamped[] transforms\n",
    "std_msgs/String": "string data\n",
    "sensor_msgs/CompressedImage": "std_msgs/Header header\nstring format\nuint8[] data\n",
    "nav_msgs/MapMetaData": ("builtin_interfaces/Time map_load_time\nfloat32 resolution\nuint32 width\n"
                             "uint32 height\ngeometry_msgs/Pose origin\n"),
    "nav_msgs/OccupancyGrid": "std_msgs/Header header\nMapMetaData info\nint8[] data\n",
}

_DEPS = {
    "std_msgs/Header": ["builtin_interfaces/Time"],
    "geometry_msgs/Pose": ["geometry_msgs/Point", "geometry_msgs/Quaternion"],
    "geometry_msgs/PoseStamped": ["std_msgs/Header", "geometry_msgs/Pose"],
    "geometry_msgs/PointStamped": ["std_msgs/Header", "geometry_msgs/Point"],
    "geometry_msgs/Transform": ["geometry_msgs/Vector3", "geometry_msgs/Quaternion"],
    "geometry_msgs/TransformStamped": ["std_msgs/Header", "geometry_msgs/Transform"],
    "tf2_msgs/TFMessage": ["geometry_msgs/TransformStamped"],
    "sensor_msgs/CompressedImage": ["std_msgs/Header"],
    "nav_msgs/MapMetaData": ["builtin_interfaces/Time", "geometry_msgs/Pose"],
    "nav_msgs/OccupancyGrid": ["std_msgs/Header", "nav_msgs/MapMetaData"],
}


def msgdef(name: str) -> str:
    """The full definition of ``name`` (e.g. ``geometry_msgs/PoseStamped``): its own fields, then
    every message it uses, each after a separator line and ``MSG: pkg/Name``."""
    order: list[str] = []

    def visit(n: str) -> None:
        for d in _DEPS.get(n, []):
            if d not in order:
                order.append(d)
                visit(d)

    visit(name)
    return _DEFS[name] + "".join(f"{_SEP}MSG: {d}\n{_DEFS[d]}" for d in order)

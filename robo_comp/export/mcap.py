"""A match's event log as an MCAP file that Foxglove and ROS 2 tools open.

``robo-comp export mcap STATE/events.log OUT.mcap`` reads the log through
:func:`robo_comp.protocol.logfile.read_recording` and writes ROS 2 messages (``ros2`` profile,
``ros2msg`` schemas, CDR: what ``ros2 bag record -s mcap`` writes, via ``mcap-ros2-support``):

==========================  ============================  ===============================================
topic                       type                          from
==========================  ============================  ===============================================
``/arena/map``              ``nav_msgs/OccupancyGrid``     the arena's walls (``core.started``): 100 wall, 0 free
``/robots/tagTAG/pose``     ``geometry_msgs/PoseStamped``  ``robot.registered`` and ``robot.positions``
``/tf``                     ``tf2_msgs/TFMessage``         the same poses as transforms ``arena`` -> ``robot_TAG``
``/tasks``                  ``std_msgs/String`` (JSON)     ``task.given``, ``task.started``, ``task.done``, ``robot.stopped``
``/finds``                  ``std_msgs/String`` (JSON)     ``find.reported`` (with the judge's verdict)
``/finds/point``            ``geometry_msgs/PointStamped`` where each find was reported
``/pictures``               ``sensor_msgs/CompressedImage`` each ``picture``, the PNG from ``STATE/pictures/ID.png``
``/pictures/meta``          ``std_msgs/String`` (JSON)     each ``picture``'s record (robot, pose, victims seen)
``/score``                  ``std_msgs/String`` (JSON)     ``score`` (the scoreboard)
``/events``                 ``std_msgs/String`` (JSON)     every record the view sees (topic, team, data; bytes as length)
==========================  ============================  ===============================================

**Views.** What goes into the file is one view of the match, from the one visibility table
(:class:`robo_comp.protocol.topics.EventView`): ``public`` (the default: a file to hand out carries
what the public feeds carried, so no private topic, no private field, no picture's image),
``team:NAME`` (what that team's consoles were sent: its own records whole and its own pictures, the
events for everyone, its own robots' poses) or ``referee`` (every record and picture). Records the
view does not see are left out of every topic, ``/events`` too.

A robot's topic names its tag after ``tag`` (``/robots/tag101/pose``): a ROS 2 name may not
start a segment with a digit. ``/tf`` carries one message per record of poses (a transform per
robot in it), so Foxglove's 3D panel draws each robot's frame ``robot_TAG`` (the frame of its
pictures too) on the map. Frame ``arena``: metres, x east along the map's columns, y **up** the map (the arena's y points
down its rows, so y is negated), yaw counter-clockwise (minus the arena's clockwise heading),
cell ``(i, j)``'s centre at ``(i·s, −j·s)`` for the cell size ``s``: the map looks in Foxglove's
3D panel as it does on the wall. Times are the log's (Unix time of each record).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robo_comp.errors import FieldError, UnavailableError
from robo_comp.export.ros2msgs import msgdef
from robo_comp.protocol import EventView, unpack_walls
from robo_comp.protocol.logfile import LogRecord, read_recording

FRAME = "arena"
TASK_TOPICS = ("task.given", "task.started", "task.done", "robot.stopped")


@dataclass(slots=True)
class ExportSummary:
    """What an export wrote: messages per topic, records read, pictures missing."""

    out: Path
    records: int
    messages: dict[str, int]
    missing_pictures: list[int]
    view: str = "public"
    #: Records of the log the view does not see (left out).
    withheld: int = 0


def _stamp(t: float) -> dict[str, int]:
    """``t`` seconds as a ROS 2 time (the fraction to the nanosecond, rounding up into the next
    second where it must)."""
    sec = math.floor(t)
    extra, nanosec = divmod(round((t - sec) * 1e9), 1_000_000_000)
    return {"sec": int(sec + extra), "nanosec": int(nanosec)}


def _header(t: float, frame: str = FRAME) -> dict[str, Any]:
    return {"stamp": _stamp(t), "frame_id": frame}


def _plain(v: Any) -> Any:
    """``v`` as JSON can hold it (bytes become a note of their length)."""
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, (bytes, bytearray, memoryview)):
        return f"<{len(v)} bytes>"
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def _json(v: Any) -> dict[str, str]:
    return {"data": json.dumps(_plain(v), sort_keys=True, separators=(",", ":"))}


class _Frames:
    """Arena cells and degrees to the ``arena`` frame's metres and quaternions."""

    def __init__(self, cell_cm: float) -> None:
        self.s = cell_cm / 100.0

    def point(self, x: float, y: float) -> dict[str, float]:
        return {"x": x * self.s, "y": -y * self.s, "z": 0.0}

    def pose(self, x: float, y: float, heading: float) -> dict[str, Any]:
        yaw = -math.radians(heading)
        return {"position": self.point(x, y),
                "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}}

    def transform(self, t: float, tag: Any, pose: dict[str, Any]) -> dict[str, Any]:
        """Robot ``tag``'s ``pose`` as the transform from ``arena`` to its frame ``robot_TAG``."""
        return {"header": _header(t), "child_frame_id": f"robot_{tag}",
                "transform": {"translation": pose["position"], "rotation": pose["orientation"]}}


def view_name(view: str, teams: list[str]) -> str:
    """The :class:`EventView` name of ``--view`` (``public``, ``referee`` or ``team:NAME`` of one of
    ``teams``); a clear error for anything else."""
    if view in ("public", "referee"):
        return view
    if view.startswith("team:") and view[5:] in teams:
        return view[5:]
    known = ", ".join(f"team:{t}" for t in teams) or "none in this log"
    raise FieldError(f"--view {view!r}: give public (a file to hand out), referee (everything) or team:NAME "
                     f"for one of the match's teams ({known})")


def export_mcap(log: Path, out: Path, pictures: Path | None = None, view: str = "public") -> ExportSummary:
    """Write view ``view`` (``public``, ``team:NAME`` or ``referee``) of the match of event log ``log``
    to ``out`` as MCAP (see the module's docstring). ``pictures``: the folder of the match's PNGs
    (default: ``pictures/`` beside the log)."""
    try:
        from mcap_ros2.writer import Writer
    except ImportError:
        raise UnavailableError("the MCAP export needs mcap and mcap-ros2-support: pip install 'robo_comp[mcap]'") from None

    records, started = read_recording(log)
    name = view_name(view, [str(t) for t in started.get("teams", [])])
    see = EventView(name)
    arena = started["arena"]
    frames = _Frames(float(arena.get("cell_cm", 25.0)))
    pictures = pictures if pictures is not None else log.parent / "pictures"
    counts: dict[str, int] = {}
    missing: list[int] = []
    withheld = 0
    out.parent.mkdir(parents=True, exist_ok=True)
    try:
        stream = open(out, "wb")
    except OSError as e:
        raise FieldError(f"cannot write {out}: {e.strerror}") from None
    with stream:
        w = Writer(stream)
        schemas: dict[str, Any] = {}

        def put(topic: str, kind: str, msg: dict[str, Any], t: float) -> None:
            schema = schemas.get(kind)
            if schema is None:
                schema = schemas[kind] = w.register_msgdef(kind, msgdef(kind))
            ns = int(round(t * 1e9))
            w.write_message(topic, schema, msg, log_time=ns, publish_time=ns, sequence=counts.get(topic, 0))
            counts[topic] = counts.get(topic, 0) + 1

        w.add_metadata("robo_comp", {"log": str(log), "arena": str(arena.get("name", "")),
                                     "cell_cm": str(arena.get("cell_cm", "")), "frame": FRAME, "view": view,
                                     "teams": ",".join(map(str, started.get("teams", [])))})
        for rec in records:
            d = see(rec.topic, rec.team, rec.data)
            if d is None:
                withheld += 1
                continue
            # a picture's image goes only to its own team and the referee (not in the public feeds)
            image = name == "referee" or (name != "public" and (d.get("team") or rec.team) == name)
            _one(rec, d, put, frames, pictures if image else None, missing)
            put("/events", "std_msgs/String", _json({"seq": rec.seq, "topic": rec.topic, "team": rec.team,
                                                     "data": d}), rec.t)
        w.finish()
    return ExportSummary(out, len(records), counts, missing, view, withheld)


def _one(rec: LogRecord, d: dict[str, Any], put: Any, frames: _Frames, pictures: Path | None,
         missing: list[int]) -> None:
    """The messages of one record (its data ``d`` as the view sees it) on their own topics; a
    picture's image only where ``pictures`` is given."""
    t = rec.t
    if rec.topic == "core.started" and "arena" in d:
        a = d["arena"]
        walls = unpack_walls(a)
        h, wd = walls.shape
        s = frames.s
        # OccupancyGrid rows go up +y from the origin: the arena's last row first
        data = [100 if walls[h - 1 - r, c] else 0 for r in range(h) for c in range(wd)]
        origin = {"position": {"x": -0.5 * s, "y": -(h - 0.5) * s, "z": 0.0},
                  "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}
        put("/arena/map", "nav_msgs/OccupancyGrid",
            {"header": _header(t), "info": {"map_load_time": _stamp(t), "resolution": s, "width": wd, "height": h,
                                            "origin": origin}, "data": data}, t)
    elif rec.topic in ("robot.registered", "robot.positions"):
        rows = ([(d["tag"], d["x"], d["y"], d.get("heading", 0.0))] if rec.topic == "robot.registered" else
                list(zip(d.get("tags", []), d.get("x", []), d.get("y", []), d.get("heading", []))))
        tf = []
        for tag, x, y, h in rows:
            pose = frames.pose(x, y, h)
            put(f"/robots/tag{tag}/pose", "geometry_msgs/PoseStamped", {"header": _header(t), "pose": pose}, t)
            tf.append(frames.transform(t, tag, pose))
        if tf:
            put("/tf", "tf2_msgs/TFMessage", {"transforms": tf}, t)
    elif rec.topic in TASK_TOPICS:
        put("/tasks", "std_msgs/String", _json(dict(d, event=rec.topic, team=rec.team)), t)
    elif rec.topic == "find.reported":
        put("/finds", "std_msgs/String", _json(d), t)
        put("/finds/point", "geometry_msgs/PointStamped",
            {"header": _header(t), "point": frames.point(d["x"], d["y"])}, t)
    elif rec.topic == "picture":
        put("/pictures/meta", "std_msgs/String", _json(d), t)
        if pictures is None:
            return
        png = pictures / f"{int(d['id'])}.png"
        try:
            blob = png.read_bytes()
        except OSError:
            missing.append(int(d["id"]))
            return
        put("/pictures", "sensor_msgs/CompressedImage",
            {"header": _header(t, f"robot_{d.get('tag')}"), "format": "png", "data": blob}, t)
    elif rec.topic == "score":
        put("/score", "std_msgs/String", _json(d), t)

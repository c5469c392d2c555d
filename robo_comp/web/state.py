"""What a page is sent: the match as JSON-ready data, and the public view of logged events.

The gateway keeps one :class:`robo_comp.view.model.MatchView` per view (the same model the
display wall draws from) and turns it into the page's ``state`` message with :func:`state_json`;
after that the page applies the events itself (``static/model.js`` mirrors the model's
handlers). The map is sent once, as a PNG with one pixel per cell coloured like the wall's
(walls, costly cells, zones and start zones), which the page scales up without smoothing.
"""
from __future__ import annotations

import base64
import os
import struct
import zlib
from typing import Any

import numpy as np

from robo_comp.protocol.topics import public_event
from robo_comp.view.legend import legend_colours
from robo_comp.view.model import MatchView, find_state

# The map is drawn in the wall's colours, from its pygame module: without pygame's greeting on stdout.
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

#: The fields of a robot row and of a find that the public view shows (those the PUB feed carries).
PUBLIC_ROBOT = ("tag", "team", "status", "x", "y", "heading", "moving")
PUBLIC_FIND = ("id", "team", "tag", "x", "y", "kind", "state")
#: Robots sent as rows ``[tag, team, x, y, heading, status, moving, task, trail]`` (``trail``: the
#: last :data:`TRAIL_SENT` trail points as a flat ``[x0, y0, x1, y1, ...]``).
ROBOT_FIELDS = ("tag", "team", "x", "y", "heading", "status", "moving", "task", "trail")
#: Trail points per robot in a ``state`` message (a page that joins or seeks sees where robots were).
TRAIL_SENT = 24


def public_snapshot(snap: dict[str, Any]) -> dict[str, Any]:
    """A ``snapshot`` reply cut down to what the PUB feed would show anyone (the public view)."""
    out = dict(snap)
    out["robots"] = [{**{k: r[k] for k in PUBLIC_ROBOT if k in r}, "task": _task_name(r.get("task"))}
                     for r in snap.get("robots") or []]
    out["finds"] = [{**{k: f[k] for k in PUBLIC_FIND if k in f}, "state": find_state(f)}
                    for f in snap.get("finds") or []]
    out["videos"] = [public_event("video", v) for v in snap.get("videos") or []]
    return out


def _task_name(task: Any) -> dict[str, Any] | None:
    """A task as the PUB feed names it (``task.started`` carries its name and id, not its arguments)."""
    if isinstance(task, dict) and task.get("name"):
        return {"name": task["name"], "task_id": task.get("task_id")}
    return None


def jsonable(v: Any) -> Any:
    """Plain data for ``json.dumps``: bytes become base64 text, numpy scalars numbers, tuples lists."""
    if isinstance(v, dict):
        return {str(k): jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [jsonable(x) for x in v]
    if isinstance(v, (bytes, bytearray, memoryview)):
        return base64.b64encode(bytes(v)).decode()
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, float) and v != v:  # NaN is not JSON
        return None
    return v


def png_rgb(img: np.ndarray) -> bytes:
    """Encode an ``[h, w, 3]`` uint8 array as a PNG (no dependency beyond zlib)."""
    h, w = img.shape[:2]
    raw = b"".join(b"\x00" + img[y].tobytes() for y in range(h))

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))


def map_png(model: MatchView) -> str:
    """The map as a ``data:`` URL: one pixel per cell, coloured as the display wall colours it."""
    from robo_comp.view.colours import cell_colours

    assert model.arena is not None
    return "data:image/png;base64," + base64.b64encode(png_rgb(cell_colours(model.arena))).decode()


def state_json(model: MatchView, now: float, *, map_url: str | None = None,
               tasks: dict[int, str] | None = None) -> dict[str, Any]:
    """The page's ``state`` message body: arena (with the map image), robots, things, score,
    the match clock as of ``now`` (the model's clock) and the message bar."""
    a = model.arena
    arena = None
    if a is not None:
        arena = {"name": a.name, "width": a.width, "height": a.height, "cell_cm": a.cell_cm, "teams": a.teams,
                 "zones": a.zones, "objects": a.objects, "map": map_url if map_url is not None else map_png(model)}
    tasks = tasks or {}
    robots = [[r.tag, r.team, round(r.x, 3), round(r.y, 3), round(r.heading, 1), r.status, r.moving,
               tasks.get(r.tag), [round(v, 1) for p in list(r.trail)[-TRAIL_SENT:] for v in p]]
              for r in model.robots.values()]
    things = [{"kind": t.kind, "id": t.id, "x": t.x, "y": t.y, "team": t.team, "state": t.state, "info": t.info}
              for t in model.things.values() if t.kind != "object"]
    m = model.match
    elapsed, remaining = m.now(now)
    return jsonable({"arena": arena, "robots": robots, "things": things, "score": model.score,
                     "legend": legend_colours(model) if a is not None else None,
                     "match": {"phase": m.phase, "elapsed": elapsed, "remaining": remaining},
                     "debug": [[tag, frame] for tag, frame in sorted(model.debug.items())],
                     "messages": [{"text": x.text, "level": x.level} for x in model.visible_messages(now)]})


class TaskNames:
    """The name of each robot's current task, from the public ``task.*`` events (names are public)."""

    def __init__(self) -> None:
        self.names: dict[int, str] = {}

    def apply(self, topic: str, d: dict[str, Any]) -> None:
        """Follow ``task.started`` / ``task.done`` / ``robot.stopped``."""
        tag = d.get("tag")
        if not isinstance(tag, int):
            return
        if topic == "task.started":
            self.names[tag] = str(d.get("name", ""))
        elif topic in ("task.done", "robot.stopped", "robot.left"):
            self.names.pop(tag, None)

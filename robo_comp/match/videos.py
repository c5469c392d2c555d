"""The videos robots filmed: numbered and announced by the match, the same live and on the engine.

A video is evidence like a picture (``examineArea`` films its turn on the spot): the robot's host
sends the WebM file (live: the core's ``video`` request, which keeps the file in the state folder;
on the engine: kept in memory), and the match gives it the next id and says so in a ``video``
event (the public sees that a robot filmed, where and for how long; the film is its team's and
the referee's). The pose is the one the match judges (``Match.judged_pose``), as for a picture.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from robo_comp.match.output import MatchOutput

#: The largest video a robot may send (bytes of WebM).
MAX_VIDEO = 512 * 1024


class Videos:
    """The match's videos: their records by id (the files are the driver's)."""

    def __init__(self, out: MatchOutput, wall: Callable[[], float]) -> None:
        self.out = out
        self.wall = wall
        self.records: dict[int, dict[str, Any]] = {}
        self.next_id = 1

    def record(self, team: str, tag: int, x: float, y: float, heading: float, **meta: Any) -> dict[str, Any]:
        """A video robot ``tag`` of ``team`` filmed at the judged pose (``meta``: ``seconds``,
        ``frames``, ``label``, ``sha256``): recorded, announced, returned with its ``id``."""
        rec = {"id": self.next_id, "tag": tag, "team": team, "x": x, "y": y, "heading": heading,
               "t": self.wall(), **meta}
        self.next_id += 1
        self.records[rec["id"]] = rec
        self.out.emit("video", team, dict(rec))
        return rec

    def restore(self, rec: dict[str, Any]) -> None:
        """Take back a video recorded earlier (recovery from the event log)."""
        vid = int(rec["id"])
        self.records[vid] = dict(rec)
        self.next_id = max(self.next_id, vid + 1)


__all__ = ["MAX_VIDEO", "Videos"]

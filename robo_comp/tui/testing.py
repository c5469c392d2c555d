"""Helpers for testing the consoles: a canned link for snapshots and a pilot wait.

:class:`CannedLink` answers like a core from fixed data (no sockets, no clock), so snapshot
tests draw the same screen every time. :func:`until` waits, inside ``App.run_test()``, for
a condition that a real core makes true.
"""
from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from robo_comp.errors import UnknownTypeError, error_from_code
from robo_comp.link import EventSink, LinkState, StateSink

GO_TO = {"name": "goTo", "description": "drive to a cell along a planned path",
         "args": [{"name": "x", "type": "int", "description": "target column"},
                  {"name": "y", "type": "int", "description": "target row"}]}
FOLLOW = {"name": "followPath", "description": "visit several cells in order",
          "args": [{"name": "points", "type": "points", "description": "cells to visit in order, [[x, y], ...]"}]}
EXAMINE = {"name": "examineArea", "description": "go to a cell, turn 360 degrees and take pictures",
           "args": [{"name": "x", "type": "int", "description": "target column"},
                    {"name": "y", "type": "int", "description": "target row"}]}


def demo_walls(width: int = 24, height: int = 20) -> np.ndarray:
    """The default arena's walls: an outer wall and a room with a door."""
    w = np.zeros((height, width), dtype=bool)
    w[0, :] = w[-1, :] = w[:, 0] = w[:, -1] = True
    w[6, 8:16] = True
    w[7:13, 8] = w[7:13, 15] = True
    w[13, 8:11] = w[13, 13:16] = True
    return w


def demo_data(role: str = "team", team: str | None = "red") -> dict[str, Any]:
    """A fixed match: two teams, five robots, one find, scores and a paused clock."""
    walls = demo_walls()
    h, w = walls.shape
    robots = [
        {"tag": 101, "team": "red", "robot_id": "red-1", "status": "connected", "x": 3.0, "y": 4.0,
         "heading": 90.0, "moving": True, "task": {"task_id": 7, "name": "goTo", "args": [12, 15]}, "queue": 1},
        {"tag": 102, "team": "red", "robot_id": "red-2", "status": "connected", "x": 18.0, "y": 3.0,
         "heading": 180.0, "moving": False, "task": None, "queue": 0},
        {"tag": 103, "team": "red", "robot_id": "red-3", "status": "lost", "x": 5.0, "y": 16.0,
         "heading": 0.0, "moving": False, "task": None, "queue": 0},
        {"tag": 104, "team": "blue", "robot_id": "blue-1", "status": "connected", "x": 20.0, "y": 15.0,
         "heading": 270.0, "moving": True, "task": {"task_id": 9, "name": "examineArea", "args": [11, 9]},
         "queue": 0},
        {"tag": 105, "team": "blue", "robot_id": "blue-2", "status": "connected", "x": 12.0, "y": 17.0,
         "heading": 0.0, "moving": False, "task": None, "queue": 2},
    ]
    if role == "team":
        robots = [r for r in robots if r["team"] == team]
    detail = dict(robots[0], sensors={"range": [1.2, 3.5, 0.8, 2.0], "bumper": False, "battery": 0.87},
                  last_report=1000.0, registered_at=900.0, advertised=[GO_TO, FOLLOW, EXAMINE],
                  queued=[{"task_id": 8, "name": "examineArea", "args": [12, 15], "state": "queued"}],
                  done=[{"task_id": 3, "name": "goTo", "args": [3, 4], "ok": True, "state": "done",
                         "status": "reached (3, 4)"},
                        {"task_id": 5, "name": "followPath", "args": [[1, 1], [2, 2]], "ok": False,
                         "state": "done", "status": "blocked by a wall at (2, 2)"}])
    scores = [{"team": "red", "score": 30.0, "victims": 1, "penalties": 10.0, "rank": 1, "disqualified": False},
              {"team": "blue", "score": 20.0, "victims": 1, "penalties": 0.0, "rank": 2, "disqualified": False}]
    match = {"phase": "paused", "elapsed": 154.0, "remaining": 446.0, "duration": 600.0, "outage": "pause"}
    return {
        "hello": {"role": role, "team": team, "protocol": 2, "session": "0" * 32, "heartbeat": 1.0, "teams": ["red", "blue"],
                  "match": match},
        "snapshot": {"arena": {"name": "Default arena", "width": w, "height": h,
                               "walls": np.packbits(walls, axis=None).tobytes()},
                     "teams": ["red", "blue"], "robots": robots, "match": match, "score": scores,
                     "finds": [{"id": 1, "team": "red", "tag": 101, "x": 11.0, "y": 9.0, "state": "confirmed",
                                "verdict": {"valid": True}}]},
        "score": dict(match, teams=scores),
        "monitor": {101: detail},
        "stats": {"recovered": {"events": 1234, "seq": 1234, "seconds": 0.05, "damage": None, "damaged_copy": None,
                                "damages": [], "lost": [], "legacy_records": 0,
                                "clock": "the clock is match time as recorded: 154.0 s"}},
        "robots": robots,
        "events": [
            ("robot.registered", "red", {"tag": 101, "team": "red", "robot_id": "red-1", "x": 1.0, "y": 1.0}),
            ("task.given", "red", {"tag": 101, "task_id": 7, "name": "goTo", "args": [12, 15], "mode": "now",
                                   "by": "red"}),
            ("task.done", "red", {"tag": 101, "task_id": 5, "name": "followPath", "ok": False, "state": "done",
                                  "status": "blocked by a wall at (2, 2)"}),
            ("robot.lost", "red", {"tag": 103, "message": "no message from its host for 3.1 s"}),
            ("penalty", "red", {"team": "red", "points": -10, "reason": "robot 102 drove into the crowd"}),
            ("match.phase", "*", {"phase": "paused", "action": "pause", "by": "referee"}),
        ],
    }


class CannedLink:
    """A link that answers from :func:`demo_data`; requests not in it answer ``E_UNKNOWN_TYPE``."""

    def __init__(self, role: str = "team", team: str | None = "red", *, upload: bool = False) -> None:
        self.data = demo_data(role, team)
        self.info: dict[str, Any] = {}
        self.state = LinkState.CLOSED
        self.on_event: EventSink = lambda *_: None
        self.on_state: StateSink = lambda *_: None
        self.sent: list[tuple[str, dict[str, Any]]] = []
        self.upload = upload

    def start(self) -> None:
        self.info = dict(self.data["hello"])
        self.state = LinkState.CONNECTED
        self.on_state(LinkState.CONNECTED, "connected", self.info)
        for topic, team, data in self.data["events"]:
            self.on_event(topic, team, data)

    async def close(self) -> None:
        self.state = LinkState.CLOSED

    async def request(self, type_: str, **body: Any) -> dict[str, Any]:
        self.sent.append((type_, body))
        d = self.data
        if type_ == "snapshot":
            return d["snapshot"]
        if type_ == "score":
            return d["score"]
        if type_ == "robots":
            return {"robots": d["robots"]}
        if type_ == "monitor":
            if body.get("tag") in d["monitor"]:
                return d["monitor"][body["tag"]]
            row = next(r for r in d["robots"] if r["tag"] == body.get("tag"))
            return dict(row, advertised=[GO_TO, FOLLOW, EXAMINE], sensors={}, queued=[], done=[])
        if type_ == "stats" and self.info.get("role") == "referee":
            return d["stats"]
        if type_ == "tasks":
            return {"tag": body.get("tag"), "advertised": [GO_TO, FOLLOW, EXAMINE]}
        if type_ in ("match", "penalty", "disqualify", "broadcast", "stop", "give"):
            if not body:
                raise error_from_code("E_FIELD", f"'{type_}' needs more fields")
            return {}
        if type_ == "upload" and self.upload:
            if "source" not in body:
                raise error_from_code("E_FIELD", "'upload' needs the field 'tags'")
            if "init(robot, extra)" in body["source"]:
                raise error_from_code("E_UPLOAD", f"{body['filename']}:9: signature: init must be declared as "
                                                  "def init(robot)")
            return {"results": [{"tag": t, "ok": True, "message": "", "name": "square", "version": "1.0",
                                 "tasks": ["square"]} for t in body["tags"]]}
        if type_ == "approve" and self.upload:
            if "upload_id" not in body:
                raise error_from_code("E_FIELD", "'approve' needs the field 'upload_id'")
            return {}
        raise UnknownTypeError(f"unknown message type {type_!r}")

    async def available(self, type_: str) -> bool:
        try:
            await self.request(type_)
        except Exception as e:
            return getattr(e, "code", "") != "E_UNKNOWN_TYPE"
        return True


async def until(pilot: Any, pred: Callable[[], Any], timeout: float = 10.0, what: str = "condition") -> Any:
    """Let the app run until ``pred()`` is truthy; fail after ``timeout`` seconds."""
    t_end = time.monotonic() + timeout
    while True:
        v = pred()
        if v:
            return v
        if time.monotonic() > t_end:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        await pilot.pause(0.05)


async def until_shown(pilot: Any, app: Any, *texts: str, absent: tuple[str, ...] = (),
                      timeout: float = 15.0) -> str:
    """Let the app run until its screen shows every one of ``texts`` and none of ``absent``; return
    the screen's text then. Fail after ``timeout`` seconds with what the screen showed (a loaded
    machine may take a while to compose a screen again after a key or a message)."""
    def showing() -> str | None:
        shown = screen_text(app)
        return shown if all(t in shown for t in texts) and not any(t in shown for t in absent) else None

    what = f"the screen to show {list(texts)}" + (f" and not {list(absent)}" if absent else "")
    try:
        shown: str = await until(pilot, showing, timeout, what)
    except AssertionError as e:
        raise AssertionError(f"{e}; it shows:\n{screen_text(app)}") from None
    return shown


def screen_text(app: Any) -> str:
    """The screen as plain text (what a person would read), for assertions."""
    import io

    from rich.console import Console

    w, h = app.size
    console = Console(width=w, height=h, file=io.StringIO(), record=True, legacy_windows=False,
                      safe_box=False, color_system=None)
    console.print(app.screen._compositor.render_update(full=True, screen_stack=app._background_screens))  # noqa: SLF001
    return console.export_text()


def notifications(app: Any) -> list[str]:
    """Title and message of every notification the app raised so far (newest last)."""
    return list(app.notices)


async def settle(pilot: Any, seconds: float = 0.3) -> None:
    """Give the app a moment (workers, redraw timer) without a busy loop."""
    await asyncio.sleep(seconds)
    await pilot.pause()

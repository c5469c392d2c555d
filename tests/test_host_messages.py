"""What the core sends a robot host has a field table (protocol.messages.TO_HOST), checked on the
host as requests are checked on the core.

A real core process and a real robot host (in this process, to see what it receives): every
message the core sends it in a match (tasks, an interrupt, a stop, the radio, an upload, an
unload, the extensions asked, a sandbox reset, a handover, the match held and resumed, map
deltas, heartbeats) fits the table; a message that does not (a task without its arguments, a
robot tag that is text, a type hosts do not take) is logged and ignored, and the host goes on.
"""
from __future__ import annotations

import threading
import time
from typing import Any

import msgpack

from conftest import next_event_where, wait_for, wait_robots
from robo_comp import protocol as P
from robo_comp.client import Client, resolve_core
from robo_comp.robots.host import RobotHost

SQUARE = ('MANIFEST = {"name": "sq", "version": "1", "kind": "extension", "tasks": {"hop": {"args": []}}}\n\n'
          'def hop(robot):\n    robot.radio(None, "hi")\n    robot.turn(90)\n    return robot.position()\n')


def test_every_message_a_host_gets_fits_the_table_and_a_bad_one_is_ignored(core, caplog):
    host = RobotHost(resolve_core(str(core.state)), core.host_token("red"), 2)
    seen: list[tuple[str, str | None]] = []  # (type, what was wrong or None)
    dispatch = host._dispatch

    def recording(frame: bytes) -> None:
        msg = msgpack.unpackb(frame, raw=False)
        type_ = msg.get("type") if isinstance(msg, dict) else None
        try:
            P.validate_to_host(msg)
            seen.append((type_, None))
        except Exception as e:  # noqa: BLE001 - recorded, the test says which
            seen.append((type_, str(e)))
        dispatch(frame)

    host._dispatch = recording  # type: ignore[method-assign]
    th = threading.Thread(target=host.run, kwargs={"duration": 60}, daemon=True)
    th.start()
    try:
        red = core.client("red")
        red.watch(True)
        tags = [r["tag"] for r in wait_robots(red, 2)]
        referee = Client(str(core.state), (core.state / "referee.token").read_text().strip())

        def done(tid: int) -> dict[str, Any]:
            return next_event_where(red, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == tid,
                                    20)["data"]

        assert red.upload(tags, "sq.py", SQUARE)["ok"]
        assert red.extensions(tags[0])
        assert done(red.give(tags[0], "hop")["task_id"])["ok"]  # task.start, radio to the teammate
        first = red.give(tags[1], "followPath", [[[1, 1], [1, 2], [1, 1], [1, 2]]])["task_id"]
        red.give(tags[1], "hop")  # task.interrupt
        done(first)
        red.stop(tags[1])
        red.unload(tags, "sq")
        referee.request("sandbox.reset", tags=tags)
        referee.request("match", action="finish")  # hold
        referee.request("handover", tags=[tags[0]])  # release
        wait_for(lambda: {"task.start", "task.interrupt", "stop", "radio", "upload", "unload", "extensions",
                          "sandbox.reset", "hold", "release", "heartbeat"} <= {t for t, _ in seen}, 20,
                 "every kind of message to a host")
        assert [(t, why) for t, why in seen if why is not None] == []

        # now messages that do not fit: logged, ignored, and the host goes on
        bad = [{"v": 2, "type": "task.start", "id": 0, "body": {"tag": tags[1], "task_id": 99, "name": "hop"}},
               {"v": 2, "type": "stop", "id": 7, "body": {"tag": "101"}},
               {"v": 2, "type": "teleport", "id": 0, "body": {"tag": tags[1]}},
               ["not", "a", "map"]]
        before = len(seen)
        with caplog.at_level("ERROR", logger="robo_comp.robots"):
            for m in bad:
                recording(msgpack.packb(m, use_bin_type=True))
        assert [why is not None for _, why in seen[before:]] == [True] * len(bad)
        said = " ".join(r.getMessage() for r in caplog.records)
        assert "needs the field 'args'" in said and "'tag' of 'stop' must be int" in said and "'teleport'" in said
        assert host.by_tag[tags[1]].task is None  # the task that lacked its arguments never started
        time.sleep(0.3)
        assert th.is_alive()
        assert [r["tag"] for r in wait_robots(red, 1)] == [tags[1]]  # the robot it kept is still reported
        referee.close()
    finally:
        host.stop()
        th.join(10)

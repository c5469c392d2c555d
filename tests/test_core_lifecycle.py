"""Robots come and go: tags kept across reconnects, lost detection, core loss, leaving."""
from __future__ import annotations

import json
import signal
import time

import pytest

from conftest import HEARTBEAT, next_event_where, wait_for, wait_robots
from robo_comp import protocol as P
from robo_comp.launch import start_core, stop_all


@pytest.mark.core_args("--robots", "4")  # the built-in arena gives each team 3: the organiser allows a 4th
def test_reconnect_keeps_the_tag(core):
    p = core.robots("red", 3, "--prefix", "alpha")
    red = core.client("red")
    red.watch(True)
    before = {r["robot_id"]: r["tag"] for r in wait_robots(red, 3)}
    p.kill()
    p.wait()
    wait_robots(red, 3, status="lost", timeout=5)
    core.robots("red", 3, "--prefix", "alpha")
    after = {r["robot_id"]: r["tag"] for r in wait_robots(red, 3)}
    assert after == before
    ev = next_event_where(red, lambda e: e["topic"] == "robot.returned")
    assert ev["data"]["tag"] in before.values()
    # a different prefix makes new robots with new tags
    core.robots("red", 1, "--prefix", "beta")
    rows = wait_robots(red, 4)
    assert len({r["tag"] for r in rows}) == 4


def test_lost_detection_and_return(core):
    p = core.robots("blue", 2)
    blue = core.client("blue")
    blue.watch(True)
    tags = [r["tag"] for r in wait_robots(blue, 2)]
    t0 = time.monotonic()
    p.send_signal(signal.SIGSTOP)  # the host falls silent without closing its socket
    try:
        ev = next_event_where(blue, lambda e: e["topic"] == "robot.lost", timeout=5)
        assert ev["data"]["tag"] in tags
        assert time.monotonic() - t0 < 3 * HEARTBEAT + 3.0  # 3 beats of silence, a tick, slack for load
        wait_for(lambda: {r["status"] for r in blue.robots()} == {"lost"}, 3, "both robots lost")
    finally:
        p.send_signal(signal.SIGCONT)
    next_event_where(blue, lambda e: e["topic"] == "robot.returned", timeout=10)
    rows = wait_robots(blue, 2)
    assert [r["tag"] for r in rows] == tags


def test_robots_halt_when_the_core_is_gone_and_reconnect_with_their_tags(core):
    core.robots("red", 1, "--speed", "1")
    red = core.client("red")
    row = wait_robots(red, 1)[0]
    walls = P.unpack_walls(red.arena())
    far = max(((x, y) for y in range(walls.shape[0]) for x in range(walls.shape[1]) if not walls[y, x]),
              key=lambda c: abs(c[0] - row["x"]) + abs(c[1] - row["y"]))
    red.give(row["tag"], "goTo", list(far))
    wait_for(lambda: red.monitor(row["tag"])["moving"], 5, "moving")
    core.proc.send_signal(signal.SIGSTOP)  # the core freezes: robots must notice and halt
    time.sleep(3 * HEARTBEAT + 1.0)
    core.proc.send_signal(signal.SIGCONT)
    wait_for(lambda: red.monitor(row["tag"])["status"] == "connected", 10, "robot back")
    m = red.monitor(row["tag"])
    assert m["tag"] == row["tag"]
    log = (core.state / "robots-red.log").read_text()
    assert "lost the core" in log and "halting robots and reconnecting" in log
    # the task survives the outage and goes on
    assert m["task"] is not None and m["task"]["args"] == list(far)


def test_a_restarted_core_serves_returning_hosts(tmp_path):
    state = tmp_path / "s"
    core = start_core(state, "--heartbeat", str(HEARTBEAT))
    port = json.loads((state / "core.json").read_text())["router"].rsplit(":", 1)[1]
    from robo_comp.client import Client
    from robo_comp.launch import start_robots
    host = start_robots(state, "red", 2)
    try:
        tok = (state / "teams/red.token").read_text().strip()
        c = Client(str(state), tok)
        wait_robots(c, 2)
        c.close()
        stop_all([core])
        core = start_core(state, "--heartbeat", str(HEARTBEAT), port=int(port))
        c = Client(str(state), tok)  # tokens are kept in the state folder across restarts
        rows = wait_robots(c, 2, timeout=15)
        assert {r["robot_id"] for r in rows} == {"red-1", "red-2"}
        c.close()
    finally:
        stop_all([core, host])


def test_leaving_robots_are_marked_left(core):
    p = core.robots("red", 1)
    red = core.client("red")
    wait_robots(red, 1)
    p.terminate()  # a clean exit says leave for each robot
    p.wait(5)
    assert wait_robots(red, 1, status="left", timeout=5)[0]["status"] == "left"

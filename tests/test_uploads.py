"""Uploads of team code through the real core to real robot hosts and their sandboxes:
the checked contract's verdicts, tasks from uploads, code replacing a built-in, stop and
interrupt of team code, versions, unload, ownership, approval, and the ctl command."""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import wait_for, wait_robots
from robo_comp.protocol import unpack_walls
from robo_comp.errors import BadTaskError, NotYoursError, UploadError

TEMPLATES = Path(__file__).parent.parent / "team_templates" / "extensions"

PROBE = '''
MANIFEST = {"name": "probe", "version": "VERSION", "kind": "extension",
            "tasks": {"probe": {"args": [{"name": "x", "type": "int"}, {"name": "y", "type": "int"}]},
                      "spin": {"args": []}}}

def probe(robot, x, y):
    start = robot.position()
    robot.turn(90)
    robot.go_to(x, y)
    print("probe at", robot.position())
    return {"start": start, "end": robot.position(), "sense": robot.sense(), "version": "VERSION",
            "plan": len(robot.plan(x, y))}

def spin(robot):
    while True:
        robot.turn(90)
'''

BROKEN = '''MANIFEST = {"name": "probe", "version": "9", "kind": "extension",
            "tasks": {"probe": {"args": []}}}

def probe(robot):
    return robot.__class__
'''


@pytest.fixture
def team(core):
    core.robots("red", 2, "--speed", "6")
    red = core.client("red", timeout=30.0)
    red.watch(True)
    rows = wait_robots(red, 2)
    walls = unpack_walls(red.arena())
    return core, red, rows, walls


def near_free(walls, row, dist=2):
    """A free cell about ``dist`` cells from the robot."""
    free = [(x, y) for y in range(walls.shape[0]) for x in range(walls.shape[1]) if not walls[y, x]]
    return min(free, key=lambda c: (abs(abs(c[0] - round(row["x"])) + abs(c[1] - round(row["y"])) - dist), c))


def event(c, pred, timeout=10.0):
    """The first pushed event matching ``pred``, looking first at those already read."""
    seen = c.__dict__.setdefault("seen", [])
    for ev in seen:
        if pred(ev):
            return ev
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        ev = c.next_event(0.2)
        if ev is not None:
            seen.append(ev)
            if pred(ev):
                return ev
    raise AssertionError("timed out waiting for a matching event")


def done_event(c, task_id, timeout=20.0):
    return event(c, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == task_id, timeout)["data"]


def advertised(c, tag):
    return {t["name"] for t in c.tasks(tag)["advertised"]}


def test_upload_adds_tasks_to_that_robot_only_and_they_run(team):
    core, red, rows, walls = team
    a, b = rows[0]["tag"], rows[1]["tag"]
    out = red.upload([a], "probe.py", PROBE.replace("VERSION", "1"))
    assert out["ok"] and out["results"][0]["tag"] == a and out["results"][0]["name"] == "probe"
    assert len(out["results"][0]["sha256"]) == 64
    wait_for(lambda: "probe" in advertised(red, a), 5, "the new task advertised")
    assert "probe" not in advertised(red, b)
    with pytest.raises(BadTaskError):
        red.give(b, "probe", [1, 1])
    assert [m["name"] for m in red.extensions(a)] == ["probe"] and red.extensions(b) == []
    target = near_free(walls, rows[0])
    tid = red.give(a, "probe", list(target))["task_id"]
    d = done_event(red, tid)
    assert d["ok"], d["status"]
    res = d["result"]
    assert res["version"] == "1" and res["plan"] >= 1 and isinstance(res["sense"], dict)
    assert abs(res["end"][0] - target[0]) < 1.5 and abs(res["end"][1] - target[1]) < 1.5
    # what team code printed reaches the team as robot.log events
    event(red, lambda e: e["topic"] == "robot.log" and "probe at" in e["data"]["text"], 5)
    # the source is kept by hash, and the event log says which code went where
    assert list((core.state / "uploads" / "red").glob("*-probe.py"))
    log = (core.state / "events.log").read_bytes()
    assert out["results"][0]["sha256"].encode() in log


def test_a_bad_upload_names_file_line_and_rule_and_the_robot_keeps_what_it_had(team):
    core, red, rows, walls = team
    a = rows[0]["tag"]
    red.upload([a], "probe.py", PROBE.replace("VERSION", "1"))
    with pytest.raises(UploadError) as e:
        red.upload([a], "probe.py", BROKEN)
    assert e.value.message.startswith("probe.py:5: policy"), e.value.message
    assert e.value.details["rule"] == "policy" and e.value.details["line"] == 5
    with pytest.raises(UploadError, match="syntax"):
        red.upload([a], "oops.py", "MANIFEST = {\ndef broken(:\n")
    mods = red.extensions(a)
    assert [(m["name"], m["version"]) for m in mods] == [("probe", "1")]
    tid = red.give(a, "probe", list(near_free(walls, rows[0], 1)))["task_id"]
    assert done_event(red, tid)["ok"]
    # version 2 replaces version 1 atomically; unload takes it away
    out = red.upload([a], "probe.py", PROBE.replace("VERSION", "2"))
    assert out["results"][0]["version"] == "2"
    tid = red.give(a, "probe", list(near_free(walls, rows[0], 1)))["task_id"]
    assert done_event(red, tid)["result"]["version"] == "2"
    assert red.unload([a], "probe")["tags"] == [a]
    wait_for(lambda: "probe" not in advertised(red, a), 5, "the task withdrawn")
    assert red.extensions(a) == []


def test_another_team_cannot_upload_to_my_robots(team):
    core, red, rows, walls = team
    blue = core.client("blue")
    with pytest.raises(NotYoursError):
        blue.upload([rows[0]["tag"]], "probe.py", PROBE.replace("VERSION", "1"))
    with pytest.raises(NotYoursError):
        blue.extensions(rows[0]["tag"])


def test_stop_halts_team_code_at_once_and_the_robot_stays_usable(team):
    core, red, rows, walls = team
    a = rows[0]["tag"]
    red.upload([a], "probe.py", PROBE.replace("VERSION", "1"))
    tid = red.give(a, "spin", [])["task_id"]
    event(red, lambda e: e["topic"] == "task.started" and e["data"]["task_id"] == tid, 5)
    time.sleep(0.5)
    out = red.stop(a)
    assert tid in out["cancelled"] and out["ms"] < 500
    d = done_event(red, tid)
    assert not d["ok"] and d["state"] == "cancelled"
    tid2 = red.give(a, "probe", list(near_free(walls, rows[0], 1)))["task_id"]
    d2 = done_event(red, tid2)
    assert d2["ok"], d2["status"]
    # an interrupt ends team code at the next movement boundary
    tid3 = red.give(a, "spin", [])["task_id"]
    time.sleep(0.3)
    tid4 = red.give(a, "goTo", list(near_free(walls, red.monitor(a), 1)))["task_id"]
    d3 = done_event(red, tid3)
    assert not d3["ok"] and f"interrupted by task {tid4}" in d3["status"]
    d4 = done_event(red, tid4)
    assert d4["ok"], d4["status"]


def test_code_replaces_a_builtin_task_and_ctl_uploads(team):
    core, red, rows, walls = team
    a = rows[0]["tag"]
    token = str(core.state / "teams" / "red.token")
    run = subprocess.run([sys.executable, "-m", "robo_comp.cli", "ctl", "--core", str(core.state),
                          "--token-file", token, "upload", str(a), str(TEMPLATES / "wander_code.py")],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert f"robot {a}: ok" in run.stdout
    target = near_free(walls, rows[0], 3)
    tid = red.give(a, "goTo", list(target))["task_id"]
    event(red, lambda e: e["topic"] == "robot.log" and "wander:" in e["data"]["text"], 15)
    assert done_event(red, tid, 30)["ok"]
    bad = core.state / "bad.py"
    bad.write_text(BROKEN)
    run = subprocess.run([sys.executable, "-m", "robo_comp.cli", "ctl", "--core", str(core.state),
                          "--token-file", token, "upload", str(a), str(bad)],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 1 and "E_UPLOAD" in run.stderr and "bad.py:5: policy" in run.stderr


TICK = '''
MANIFEST = {"name": "ticker", "version": "VERSION", "kind": "extension", "tasks": {"tick": {"args": []}}}

def tick(robot):
    robot.turn(90)
    return "VERSION"
'''


def test_hot_replace_under_load_loses_no_task(team):
    core, red, rows, walls = team
    tags = [r["tag"] for r in rows]
    red.upload(tags, "ticker.py", TICK.replace("VERSION", "1"))
    given = [red.give(tag, "tick", [], queue=True)["task_id"] for _ in range(6) for tag in tags]
    for v in ("2", "3"):  # new versions while the queues run
        time.sleep(0.4)
        assert red.upload(tags, "ticker.py", TICK.replace("VERSION", v))["ok"]
    results = {tid: done_event(red, tid, 60) for tid in given}
    assert all(d["ok"] for d in results.values()), [d["status"] for d in results.values() if not d["ok"]]
    versions = [d["result"] for d in results.values()]
    assert versions[0] == "1" and "3" in versions  # old code finished, new code took over

"""Task flow: now versus queued, interrupts at movement boundaries, stop, validation."""
from __future__ import annotations

import time

import pytest

from conftest import next_event_where, wait_for, wait_robots
from robo_comp.errors import BadTaskError
from robo_comp.robots.builtin_tasks import END_TOLERANCE


def _far_cell(row, walls_free):
    """A free cell far from the robot's position."""
    return max(walls_free, key=lambda c: abs(c[0] - row["x"]) + abs(c[1] - row["y"]))


@pytest.fixture
def one_robot(core):
    core.robots("red", 1, "--speed", "4")
    red = core.client("red")
    red.watch(True)
    row = wait_robots(red, 1)[0]
    from robo_comp.protocol import unpack_walls
    walls = unpack_walls(red.arena())
    free = [(x, y) for y in range(walls.shape[0]) for x in range(walls.shape[1]) if not walls[y, x]]
    return red, row, free


def done_event(red, task_id, timeout=20.0):
    return next_event_where(red, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == task_id,
                            timeout)["data"]


def test_goto_moves_cell_by_cell_and_reports_done(one_robot):
    red, row, free = one_robot
    tag = row["tag"]
    target = min(free, key=lambda c: abs(abs(c[0] - row["x"]) + abs(c[1] - row["y"]) - 4))
    tid = red.give(tag, "goTo", list(target))["task_id"]
    seen = set()
    t_end = time.monotonic() + 10
    while time.monotonic() < t_end:
        m = red.monitor(tag)
        seen.add((round(m["x"], 1), round(m["y"], 1)))
        if m["task"] is None:
            break
        time.sleep(0.05)
    d = done_event(red, tid)
    assert d["ok"] and d["state"] == "done" and d["result"]["reached"] == list(target)
    assert d["result"]["end_error"] <= END_TOLERANCE  # where the robot believes it ended
    m = red.monitor(tag)
    # teams see the positioning system's estimate (noise σ 0.25 cells), not the truth
    assert abs(m["x"] - target[0]) < 1.0 and abs(m["y"] - target[1]) < 1.0
    assert set(m["sensors"]) >= {"front", "left", "right", "down", "bump"}
    assert len(seen) >= 3  # positions were reported while moving, not just start and end
    assert m["done"][-1]["task_id"] == tid


def test_queued_waits_and_now_interrupts_at_a_movement_boundary(one_robot):
    red, row, free = one_robot
    tag = row["tag"]
    far = _far_cell(row, free)
    first = red.give(tag, "goTo", list(far))["task_id"]
    queued = red.give(tag, "goTo", [row["x"], row["y"]], queue=True)["task_id"]
    t = red.tasks(tag)
    assert t["current"]["task_id"] == first and [q["task_id"] for q in t["queued"]] == [queued]
    time.sleep(0.6)
    near = min(free, key=lambda c: abs(c[0] - row["x"]) + abs(c[1] - row["y"]) if c != (row["x"], row["y"]) else 99)
    now = red.give(tag, "goTo", list(near))
    assert now["interrupts"] == first
    d = done_event(red, first)
    assert not d["ok"] and d["state"] == "done" and f"interrupted by task {now['task_id']}" in d["status"]
    # the interrupted robot stood on a cell boundary when it switched
    ev = next_event_where(red, lambda e: e["topic"] == "task.started" and e["data"]["task_id"] == now["task_id"])
    assert ev["data"]["name"] == "goTo"
    assert done_event(red, now["task_id"])["ok"]
    # the queued task was kept through the interrupt and runs afterwards
    assert done_event(red, queued)["ok"]


def test_stop_halts_at_once_and_robot_takes_new_tasks(one_robot):
    red, row, free = one_robot
    tag = row["tag"]
    far = _far_cell(row, free)
    tid = red.give(tag, "goTo", list(far))["task_id"]
    q = red.give(tag, "goTo", list(far), queue=True)["task_id"]
    wait_for(lambda: red.monitor(tag)["moving"], 5, "robot moving")
    res = red.stop(tag)
    assert res["cancelled"] == [tid, q]
    assert res["ms"] < 1000
    m1 = red.monitor(tag)
    time.sleep(0.5)
    m2 = red.monitor(tag)
    assert (m1["x"], m1["y"]) == (m2["x"], m2["y"]) and not m2["moving"] and m2["task"] is None
    assert m2["queue"] == 0
    stopped = next_event_where(red, lambda e: e["topic"] == "robot.stopped")
    assert stopped["data"]["cancelled"] == [tid, q]
    # usable afterwards
    back = min(free, key=lambda c: abs(c[0] - m2["x"]) + abs(c[1] - m2["y"]) if c != (round(m2["x"]), round(m2["y"])) else 99)
    tid2 = red.give(tag, "goTo", list(back))["task_id"]
    assert done_event(red, tid2)["ok"]


def test_invalid_tasks_get_clear_messages(one_robot):
    red, row, free = one_robot
    tag = row["tag"]
    with pytest.raises(BadTaskError, match="has no task 'fly'; its tasks are: examineArea, followPath, goTo"):
        red.give(tag, "fly", [])
    with pytest.raises(BadTaskError, match=r"goTo takes 2 argument\(s\), got 1"):
        red.give(tag, "goTo", [1])
    with pytest.raises(BadTaskError, match="argument 'x' of goTo must be a whole number"):
        red.give(tag, "goTo", ["a", 1])
    with pytest.raises(BadTaskError, match="argument 'y' of goTo must be a whole number, got 2.5"):
        red.give(tag, "goTo", [1, 2.5])
    with pytest.raises(BadTaskError, match="followPath"):
        red.give(tag, "followPath", [[1, 2]])
    # the robot validates too: a wall cell is answered with a status message
    from robo_comp.protocol import unpack_walls
    walls = unpack_walls(red.arena())
    wall = next((x, y) for y in range(walls.shape[0]) for x in range(walls.shape[1]) if walls[y, x])
    tid = red.give(tag, "goTo", list(wall))["task_id"]
    d = done_event(red, tid)
    assert not d["ok"] and "is a wall or outside the arena" in d["status"]
    tid = red.give(tag, "goTo", [500, 500])["task_id"]
    assert "outside the arena" in done_event(red, tid)["status"]


def test_examine_area_and_follow_path(one_robot):
    red, row, free = one_robot
    tag = row["tag"]
    here = (int(row["x"]), int(row["y"]))
    near = sorted(free, key=lambda c: abs(c[0] - here[0]) + abs(c[1] - here[1]))[1:3]
    tid = red.give(tag, "followPath", [[list(near[0]), list(near[1])]])["task_id"]
    d = done_event(red, tid)
    assert d["ok"] and d["result"]["visited"] == 2 and d["result"]["end_error"] <= END_TOLERANCE
    tid = red.give(tag, "examineArea", list(near[0]))["task_id"]
    d = done_event(red, tid)
    assert d["ok"] and d["result"]["examined"] == list(near[0])
    pics = d["result"]["pictures"]
    assert len(pics) == 4 and len(set(pics)) == 4
    png = red.request("picture.get", id=pics[0])["png"]
    assert png[:8] == b"\x89PNG\r\n\x1a\n"

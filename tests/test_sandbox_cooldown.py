"""A sandbox whose code hits its limits too often rests, says for how long, comes back by
itself with the team's modules, and can be restarted by the referee (through a real core)."""
from __future__ import annotations

import pathlib
import time

import pytest

from conftest import CoreHandle, next_event_where, wait_robots
from robo_comp.errors import ForbiddenError, RoboCompError
from robo_comp.sandbox.parent import Limits, Sandbox, SandboxRestarted, SandboxStopped, TaskDone

ROOT = pathlib.Path(__file__).parent.parent
SQUARE = (ROOT / "team_templates" / "extensions" / "square.py").read_text()
#: A task that computes forever: the watchdog kills the sandbox at the wall-clock limit (a limit kill).
BOMB = '''MANIFEST = {"name": "bomb", "version": "1", "kind": "extension",
            "tasks": {"boom": {"description": "never yields", "args": []}}}


def boom(robot):
    while True:
        pass
'''
QUICK = Limits(cpu_seconds=1, memory_mib=192, wall_seconds=1.0, load_seconds=1.5, init_seconds=0.5,
               cancel_grace=0.3, max_runs=3, max_respawns=2, respawn_window=60.0, cooldown_seconds=0.5,
               max_cooldown=0.8)


def answer(tag: int, name: str, args: list) -> bool:
    return True


def _until(box: Sandbox, kind: type, timeout: float = 10.0) -> list:
    seen: list = []
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        recs = box.poll(0.05)
        seen += recs
        if any(isinstance(r, kind) for r in recs):
            return seen
    raise AssertionError(f"no {kind.__name__} within {timeout} s; saw {seen}")


def _kill_until_resting(box: Sandbox) -> SandboxStopped:
    for _ in range(QUICK.max_respawns + 1):
        box.start_task(1, "boom")
        stop = [r for r in _until(box, SandboxStopped) if isinstance(r, SandboxStopped)][-1]
        if not stop.respawned:
            return stop
    raise AssertionError("the sandbox never started resting")


def test_too_many_limit_kills_rest_then_the_sandbox_comes_back_by_itself() -> None:
    with Sandbox("red", [1], answer, QUICK) as box:
        box.load("square.py", SQUARE)
        box.load("bomb.py", BOMB)
        stop = _kill_until_resting(box)
        assert stop.cooldown == pytest.approx(0.5)
        assert "wall-clock limit (1 s) exceeded" in stop.message  # which limit
        assert "3 times within 60 s" in stop.message and "rests for 0.5 s" in stop.message
        assert "restarts by itself" in stop.message and "referee" in stop.message
        with pytest.raises(RoboCompError, match=r"resting .* restarts by itself in [1-9]\d* s"):
            box.start_task(1, "square", [1])
        restarted = [r for r in _until(box, SandboxRestarted) if isinstance(r, SandboxRestarted)][0]
        assert "cool-down is over" in restarted.message
        assert isinstance(box.run_task(1, "square", [1]), TaskDone)  # the modules came back
        stop = _kill_until_resting(box)  # again: the rest doubles, up to max_cooldown
        assert stop.cooldown == pytest.approx(0.8)


def test_reset_ends_a_rest_at_once() -> None:
    slow = Limits(**{**QUICK.__dict__, "cooldown_seconds": 600.0, "max_cooldown": 600.0})
    with Sandbox("red", [1], answer, slow) as box:
        box.load("square.py", SQUARE)
        box.load("bomb.py", BOMB)
        assert _kill_until_resting(box).cooldown == 600.0
        assert box.reset() is True
        assert isinstance(box.run_task(1, "square", [1]), TaskDone)
        assert box.reset() is False  # running: nothing to restart, the count starts again


def test_only_the_referee_resets_a_sandbox_through_the_core(core: CoreHandle) -> None:
    core.robots("red", 1)
    red = core.client("red")
    tag = wait_robots(red, 1)[0]["tag"]
    assert red.upload([tag], "square.py", SQUARE)["ok"]
    with pytest.raises(ForbiddenError, match="only the referee"):
        red.sandbox_reset([tag])
    row = core.referee().sandbox_reset([tag])["results"][0]
    assert (row["tag"], row["ok"], row["restarted"]) == (tag, True, False)  # it was running
    assert "starts again from zero" in row["message"]
    assert any(e["topic"] == "sandbox.reset" for e in core.logged_events())


@pytest.mark.slow
def test_the_referee_restarts_a_resting_sandbox_through_the_core(core: CoreHandle) -> None:
    core.robots("red", 1)
    red = core.client("red")
    tag = wait_robots(red, 1)[0]["tag"]
    assert red.upload([tag], "square.py", SQUARE)["ok"]
    assert red.upload([tag], "bomb.py", BOMB)["ok"]
    red.watch(True)
    for kills in range(1, 10):  # the host's default: 5 respawns a minute, the sixth kill rests 60 s
        red.give(tag, "boom", [])
        stop = next_event_where(red, lambda e: e["topic"] == "robot.log" and "sandbox stopped" in e["data"]["text"],
                                20.0)
        if "rests for" in stop["data"]["text"]:
            break
    assert kills == 6 and "rests for 60 s" in stop["data"]["text"], stop
    assert "wall-clock limit" in stop["data"]["text"]
    with pytest.raises(ForbiddenError, match="only the referee"):
        red.sandbox_reset([tag])
    out = core.referee().sandbox_reset([tag])
    assert out["results"] == [{"tag": tag, "ok": True, "restarted": True, "message": out["results"][0]["message"]}]
    next_event_where(red, lambda e: e["topic"] == "robot.log" and "referee restarted" in e["data"]["text"], 10.0)
    given = red.give(tag, "square", [1])
    done = next_event_where(red, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == given["task_id"], 30.0)
    assert done["data"]["ok"], done
    assert any(e["topic"] == "sandbox.reset" for e in core.logged_events())

"""The robot host plans in a process of its own (``robo_comp.robots.planning``): real host and
core processes. Killing the planner process loses no plan (the host plans them in its thread and
starts a new process); killing the host leaves no planner behind."""
from __future__ import annotations

import os
import signal
import subprocess
import time

import numpy as np
import pytest

from conftest import CoreHandle, next_event_where, wait_for, wait_robots
from robo_comp.errors import FieldError
from robo_comp.robots.planning import PROCESS_FROM, HostPlanner
from robo_comp.robots.runtime import plan_around


def planners_of(pid: int) -> list[int]:
    """The planner processes whose parent is ``pid``."""
    out = subprocess.run(["pgrep", "-P", str(pid), "-f", "robo_comp.robots.planning"],
                         capture_output=True, text=True).stdout.split()
    return [int(p) for p in out]


def test_plans_come_from_the_planner_process_and_survive_its_death() -> None:
    walls = np.zeros((40, 60), dtype=bool)
    walls[10, 0:55] = True
    hp = HostPlanner()
    try:
        first = hp.plan(walls, (1, 1), (2, 30), set()).result(timeout=60)  # the thread's, while it loads
        assert first == plan_around(walls, (1, 1), (2, 30), set())
        wait_for(hp.ready, 60, "the planner process to load its kernels")
        pid = hp.pid()
        assert pid is not None and pid != os.getpid() and hp.starts == 1
        os.kill(pid, signal.SIGSTOP)  # a plan now waits for the process: it is the process that plans
        try:
            held = hp.plan(walls, (1, 1), (3, 30), set())
            time.sleep(0.5)
            assert not held.done()
        finally:
            os.kill(pid, signal.SIGCONT)
        assert held.result(timeout=30) == plan_around(walls, (1, 1), (3, 30), set())
        walls[20, 5:60] = True  # the map changed: the process gets the new one
        assert hp.plan(walls, (1, 1), (2, 30), {(3, 3)}).result(timeout=30) == plan_around(walls, (1, 1), (2, 30), {(3, 3)})
        os.kill(pid, signal.SIGKILL)  # plans in flight are made in the host's thread
        wait_for(lambda: hp.pid() is None, 10, "the host to see its planner gone")
        futures = [hp.plan(walls, (1, 1), (59 - k, 39), set()) for k in range(20)]
        for k, f in enumerate(futures):
            assert f.result(timeout=60) == plan_around(walls, (1, 1), (59 - k, 39), set())
        assert hp.starts == 2 and hp.pid() not in (None, pid)  # the next plan started a new one
    finally:
        hp.shutdown()


def test_a_host_plans_out_of_its_process_and_leaves_no_planner_when_killed(core: CoreHandle) -> None:
    host = core.robots("red", 2, "--planner", "process")
    few = core.robots("blue", 2)  # --planner auto: a host of a few robots plans in its thread
    red = core.client("red")
    ref = core.referee()
    ref.watch(True)
    rows = wait_robots(red, 2)
    wait_robots(core.client("blue"), 2)
    wait_for(lambda: planners_of(host.pid), 30, "the host's planner process")
    time.sleep(1.0)  # both hosts are up and registered: one started its planner, the other none
    assert not planners_of(few.pid)
    [planner] = planners_of(host.pid)
    red.give(rows[0]["tag"], "goTo", [9, 1])
    done = next_event_where(ref, lambda e: e["topic"] == "task.done" and e["data"]["tag"] == rows[0]["tag"], 60)
    assert done["data"]["ok"], done["data"]
    host.kill()
    host.wait()
    wait_for(lambda: subprocess.run(["kill", "-0", str(planner)], capture_output=True).returncode != 0, 10,
             "the planner process to end with its host")


def test_a_planner_that_never_comes_up_is_not_started_again_for_every_plan() -> None:
    hp = HostPlanner()
    try:
        hp.start()
        pid = hp.pid()
        assert pid is not None
        os.kill(pid, signal.SIGKILL)  # dead before it said it was ready
        wait_for(lambda: not hp.use_process, 10, "the host to give up on the planner process")
        walls = np.zeros((10, 10), dtype=bool)
        assert hp.plan(walls, (0, 0), (9, 9), set()).result(timeout=30) == plan_around(walls, (0, 0), (9, 9), set())
        assert hp.starts == 1 and hp.pid() is None  # planned in the thread, no new process
    finally:
        hp.shutdown()


def test_where_a_host_plans_follows_its_choice_and_its_size() -> None:
    """``--planner auto`` plans in a process from PROCESS_FROM robots, in a thread below; another
    word is refused with a sentence that names the choices."""
    assert not HostPlanner.for_host("auto", PROCESS_FROM - 1).use_process
    assert HostPlanner.for_host("auto", PROCESS_FROM).use_process
    assert HostPlanner.for_host("process", 1).use_process
    assert not HostPlanner.for_host("thread", 1000).use_process
    with pytest.raises(FieldError, match="planner must be one of auto, process, thread, not 'gpu'"):
        HostPlanner.for_host("gpu", 3)

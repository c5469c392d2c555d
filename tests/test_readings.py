"""A standing robot's readings follow the world within one sensing period
(:mod:`robo_comp.robots.readings`): reported when they change beyond the sensor noise, at most once a
sensing period, never for the noise alone."""
from __future__ import annotations

import math
import time

import pytest

from conftest import wait_for
from robo_comp.client import resolve_core
from robo_comp.robots.host import RobotHost
from robo_comp.robots.readings import ReadingWatch
from robo_comp.world.arena import Arena
from robo_comp.world.scenario import default_scenario


class Standing:
    """A robot as the watch sees one: its id in the arena and a simulated driver (no own readings)."""

    def __init__(self, robot_id: str) -> None:
        self.robot_id = robot_id
        self.driver = None


def test_the_watch_reports_a_body_once_a_period_and_never_the_noise():
    world = Arena(default_scenario(), seed=3)
    world.add_robot("a-1", "red", 1, 1, 0.0)  # facing east along the free row y = 1
    world.place("a-2", "red", 10.5, 5, 0.0)  # the east wall at the edge of its front sensor's range (300 cm)
    a, edge = Standing("a-1"), Standing("a-2")
    watch = ReadingWatch(0.5)
    for r, row in zip((a, edge), world.sense_many(["a-1", "a-2"])):
        watch.sent(r.robot_id, row)
    fronts = []
    for i in range(1000):  # noise alone: nothing to report, though a-2's echo comes and goes
        assert watch.changed(world, [a, edge], 10.0 + i) == []
        fronts.append(world.sense("a-2")["front"])
    assert None in fronts and any(f is not None for f in fronts), "a-2 should stand at the edge of the range"
    world.add_robot("b-1", "blue", 4, 1, 180.0)  # three cells ahead of a-1
    assert watch.changed(world, [a, edge], 400.0) == [a]
    watch.sent("a-1", world.sense("a-1"))  # the host reports it
    world.remove_robot("b-1")
    assert watch.changed(world, [a, edge], 400.4) == []  # gone again, but a-1 reported a change 0.4 s ago
    assert watch.changed(world, [a, edge], 400.5) == [a]  # once a sensing period
    assert watch.changed(world, [a, edge], 380.0) == [a], "a clock gone back must not silence the robot"
    assert watch.changed(world, [Standing("nobody-reported")], 500.0) == []


@pytest.mark.heartbeat(5.0)  # the test drives the host's reports itself: no heartbeats meanwhile
def test_a_standing_robot_reports_a_camera_tracked_body_at_the_next_tick(core):
    """Before, a standing robot's readings went out with its once-a-second report only: the core
    did not hear of the body in front of it until then (here: never, as the test reports once)."""
    host = RobotHost(resolve_core(str(core.state)), core.host_token("red"), 1, seed=1)
    red = core.client("red")
    try:
        host._open()

        def up() -> bool:
            host.poller.poll(50)
            host._drain()
            return host.state == "up"

        wait_for(up, 20, "the host's robot registered")
        r = host.robots["red-1"]
        assert r.driver.cell() == (1, 1) and r.driver.heading == 0.0  # the first cell of red's start zone
        t0 = time.monotonic()
        host._report(t0)  # the periodic report: readings with it (nothing ahead within range)
        wait_for(lambda: "front" in (red.monitor(r.tag).get("sensors") or {}), 10, "the first readings")
        assert red.monitor(r.tag)["sensors"]["front"] is None
        assert host.world is not None
        host.foreign.fix(host.world, "blue-7", 4.0, 1.0, 180.0, t0)  # the camera sees another host's robot
        host._report(t0 + 0.1)  # the next report tick: red-1 stands and was reported 0.1 s ago
        wait_for(lambda: (red.monitor(r.tag)["sensors"]["front"] or math.inf) < 72, 10,
                 "red-1's reported front reading to see blue-7 2.5 cells ahead")
        front = red.monitor(r.tag)["sensors"]["front"]
        assert front == pytest.approx(62.5, abs=5 * host.world.scenario.sensors.noise)
    finally:
        host.code.close()
        host.planner.shutdown()
        if host.sock is not None:
            host.sock.close(0)


"""The ROS 2 driver against a simulated ROS 2 robot process, on a real DDS bus kept on loopback.

Every test sets ``CYCLONEDDS_URI`` to :func:`robo_comp.robots.ros2.bus.loopback_config`
(interface ``lo``, no multicast, peer 127.0.0.1, automatic participant indices) and uses a
domain id of its own, so no packet leaves the machine and tests running side by side do not
hear each other. The robot is ``python -m robo_comp.robots.ros2.simrobot``: it subscribes
``/NS/cmd_vel`` and publishes ``/NS/odom`` and ``/NS/scan`` as a ROS 2 robot does.
"""
from __future__ import annotations

import itertools
import math
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import pytest

pytest.importorskip("cyclonedds")

from conftest import next_event_where, wait_robots  # noqa: E402
from robo_comp.cli import main as cli_main  # noqa: E402
from robo_comp.client import resolve_core  # noqa: E402
from robo_comp.robots.host import RobotHost  # noqa: E402
from robo_comp.robots.ros2.bus import Bus, loopback_config, topic_name  # noqa: E402
from robo_comp.robots.ros2.driver import ROS2Driver  # noqa: E402
from robo_comp.robots.ros2.msgs import LaserScan, Odometry, Twist, Vector3  # noqa: E402
from robo_comp.robots.ros2.watch import CommandWatch, is_zero  # noqa: E402
from robo_comp.robots.steps import Move, Turn  # noqa: E402
from robo_comp.world.scenario import default_scenario  # noqa: E402

_ids = itertools.count()


@pytest.fixture
def domain(monkeypatch: pytest.MonkeyPatch) -> int:
    """A ROS 2 domain id of this test's own on a loopback-only DDS configuration."""
    monkeypatch.setenv("CYCLONEDDS_URI", loopback_config())
    return 1 + (os.getpid() * 7 + next(_ids)) % 100


@dataclass
class SimRobot:
    """A running simulated ROS 2 robot process."""

    proc: subprocess.Popen[str]
    ns: str

    def stop(self) -> tuple[float, float, float]:
        """End it; its true pose in the arena."""
        self.proc.send_signal(signal.SIGTERM)
        out, _ = self.proc.communicate(timeout=60)  # a loaded machine: the loop may be slow to see SIGTERM
        line = [ln for ln in out.splitlines() if ln.startswith("pose ")][-1]
        x, y, h = map(float, line.split()[1:])
        return x, y, h


def start_sim(domain: int, ns: str, x: float, y: float, heading: float = 0.0) -> SimRobot:
    """Start the simulated robot and wait for its ``ready``."""
    proc = subprocess.Popen([sys.executable, "-m", "robo_comp.robots.ros2.simrobot", "--ns", ns,
                             "--domain", str(domain), "--x", str(x), "--y", str(y), "--heading", str(heading)],
                            stdout=subprocess.PIPE, text=True, env=os.environ.copy())
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() == "ready"
    return SimRobot(proc, ns)


@pytest.fixture
def sim(domain: int) -> Iterator[SimRobot]:
    """A simulated ROS 2 robot ``tb1`` at cell (3, 3) facing +x in the built-in arena."""
    s = start_sim(domain, "tb1", 3, 3)
    yield s
    if s.proc.poll() is None:
        s.proc.kill()
        s.proc.wait()


def run_step(d: ROS2Driver, step: Any, timeout: float = 15.0) -> None:
    """Drive ``step`` to its end at the host's tick rate."""
    d.begin(step)
    t_end = time.monotonic() + timeout
    while not d.update(0.05):
        assert time.monotonic() < t_end, f"{step} did not finish"
        time.sleep(0.05)


def wait_odometry(d: ROS2Driver, timeout: float = 10.0) -> None:
    t_end = time.monotonic() + timeout
    while d.odom_count == 0:
        assert time.monotonic() < t_end, "no odometry from the simulated robot"
        d.update(0.05)
        time.sleep(0.05)


def test_messages_have_ros2_names_and_plain_cdr_layout():
    assert Twist.__idl_typename__ == "geometry_msgs::msg::dds_::Twist_"
    assert Odometry.__idl_typename__ == "nav_msgs::msg::dds_::Odometry_"
    assert LaserScan.__idl_typename__ == "sensor_msgs::msg::dds_::LaserScan_"
    assert topic_name("tb1", "cmd_vel") == "rt/tb1/cmd_vel" and topic_name("/", "odom") == "rt/odom"
    # what a ROS 2 node reads: the CDR little-endian encapsulation, then six float64 in order
    import struct

    blob = Twist(linear=Vector3(1, 2, 3), angular=Vector3(4, 5, 6)).serialize()
    assert blob[:4] == b"\x00\x01\x00\x00" and struct.unpack("<6d", blob[4:]) == (1, 2, 3, 4, 5, 6)
    assert "<NetworkInterface name=\"lo\"/>" in loopback_config()
    assert "<AllowMulticast>false</AllowMulticast>" in loopback_config()
    assert '<Peer Address="127.0.0.1"/>' in loopback_config()


def test_driver_moves_and_turns_a_ros2_robot_and_reads_its_scan(domain, sim):
    d = ROS2Driver(Bus.shared(domain), "tb1", cell_m=0.25, x=3, y=3)
    try:
        wait_odometry(d)
        run_step(d, Move(4, 3))
        run_step(d, Move(4, 4))  # face +y (clockwise on the map): a right turn for the robot
        before = d.heading
        assert 45 < before < 135, d.pose  # facing +y, roughly
        run_step(d, Turn(-90))
        x, y, h = d.pose
        assert (round(x), round(y)) == (4, 4) and abs((h - (before - 90) + 180) % 360 - 180) < 3, (before, d.pose)
        t_end = time.monotonic() + 5
        seen = d.scan_count
        while d.scan_count < seen + 2:  # a scan taken after the robot stopped
            assert time.monotonic() < t_end, "no scan"
            d.update(0.05)
            time.sleep(0.05)
        # the scan sees the arena's walls: compare with the arena's own ray caster at the true pose
        tx, ty, th = sim.stop()
        assert math.hypot(tx - x, ty - y) < 0.1 and abs((th - h + 180) % 360 - 180) < 3  # odometry = truth here
        from robo_comp.world.arena import Arena

        arena = Arena(default_scenario())
        cell_cm = arena.cell_size
        r = d.readings()
        for key, off in (("front", 0.0), ("left", -90.0), ("right", 90.0)):
            expect = arena.ray_distance(tx, ty, th + off) * cell_cm
            got = r[key]
            if expect <= 1200:
                assert got is not None and abs(got - expect) < 0.1 * cell_cm + 2, (key, r, expect)
    finally:
        d.close()


def test_halt_publishes_a_zero_twist_at_once_and_the_robot_stands(domain, sim):
    bus = Bus.shared(domain)
    listen = CommandWatch(bus, "tb1")
    d = ROS2Driver(bus, "tb1", cell_m=0.25, x=3, y=3)
    try:
        wait_odometry(d)
        d.begin(Move(4, 3))
        t_end = time.monotonic() + 5
        while not listen.got or listen.got[-1][1] == 0.0:
            assert time.monotonic() < t_end
            d.update(0.05)
            time.sleep(0.05)
        mark = listen.mark()
        d.halt()
        listen.wait(is_zero, 2.0, "zero Twist after halt", since=mark)
        assert not d.moving
        for _ in range(6):  # it stays still: odometry stops changing
            d.update(0.05)
            time.sleep(0.05)
        before = d.pose
        time.sleep(0.5)
        d.update(0.05)
        assert math.hypot(d.pose[0] - before[0], d.pose[1] - before[1]) < 0.01
        # the watchdog: a robot told to move whose driver is no longer updated is stopped
        mark = listen.mark()
        d.begin(Turn(180))
        d.update(0.05)
        listen.wait(lambda v, w: w != 0.0, 2.0, "a turn command", since=mark)
        listen.wait(is_zero, 3.0, "the watchdog's zero Twist")
    finally:
        listen.close()
        d.close()


def test_no_odometry_fails_the_step_with_a_clear_message(domain, monkeypatch):
    import robo_comp.robots.ros2.driver as drv

    monkeypatch.setattr(drv, "ODOM_TIMEOUT", 0.3)
    d = ROS2Driver(Bus.shared(domain), "nobody", cell_m=0.25, x=3, y=3)
    try:
        run_step(d, Move(4, 3), timeout=5)
        assert d.bump is not None and "no odometry from rt/nobody/odom" in d.bump["error"]
    finally:
        d.close()


def test_cli_asks_for_one_namespace_per_robot(capsys):
    assert cli_main(["robots", "--core", "tcp://127.0.0.1:1", "--token", "x", "--driver", "ros2",
                     "--count", "2", "--ros2-ns", "tb1"]) == 2
    assert "one --ros2-ns NAMESPACE per robot (2)" in capsys.readouterr().err
    assert cli_main(["robots", "--core", "tcp://127.0.0.1:1", "--token", "x", "--driver", "ros2",
                     "--count", "1", "--ros2-ns", "tb1", "--ros2-domain", "300"]) == 2
    assert "0..232" in capsys.readouterr().err


def test_a_host_drives_a_ros2_robot_for_a_real_core_and_stops_it_on_stop_and_on_a_lost_core(core, domain):
    from robo_comp.protocol import unpack_walls

    bus = Bus.shared(domain)
    listen = CommandWatch(bus, "tb1")
    sim = None
    host = RobotHost(resolve_core(str(core.state)), core.host_token("red"), 1, driver="ros2", seed=3,
                     driver_options={"ros2_ns": ["tb1"], "ros2_domain": domain, "ros2_speed": 0.25})
    th = threading.Thread(target=host.run, kwargs={"duration": 60}, daemon=True)
    th.start()
    try:
        red = core.client("red")
        red.watch(True)
        row = wait_robots(red, 1)[0]
        x, y = round(row["x"]), round(row["y"])
        sim = start_sim(domain, "tb1", x, y)  # the robot stands where the host placed it
        walls = unpack_walls(red.arena())

        def free(cx: int, cy: int) -> bool:
            return 0 <= cx < walls.shape[1] and 0 <= cy < walls.shape[0] and not walls[cy, cx]

        target = next((x + dx, y + dy) for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)) if free(x + dx, y + dy))
        tid = red.give(row["tag"], "goTo", list(target))["task_id"]
        done = next_event_where(red, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == tid, 30)
        assert done["data"]["ok"], done["data"]
        m = red.monitor(row["tag"])
        assert (round(m["x"]), round(m["y"])) == target  # odometry's pose is what it reports
        assert m.get("sensors") is None or "front" in m["sensors"]

        # stop: a zero Twist at once, in the middle of a move
        far = next(((target[0] + k * dx, target[1] + k * dy) for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1))
                    for k in (3,) if all(free(target[0] + j * dx, target[1] + j * dy) for j in range(1, 4))), None)
        if far is None:
            pytest.skip("no straight free run of 3 cells next to the robot in this arena")
        mark = listen.mark()
        red.give(row["tag"], "goTo", list(far))
        listen.wait(lambda v, w: v > 0.0, 10, "a forward command", since=mark)
        mark = listen.mark()
        red.stop(row["tag"])
        listen.wait(is_zero, 3, "zero Twist after stop", since=mark)

        # a lost core: the host stops the robot (zero Twist) and does not drive on
        mark = listen.mark()
        red.give(row["tag"], "goTo", list(far))  # stopped on the way: far is still ahead
        listen.wait(lambda v, w: v != 0.0 or w != 0.0, 10, "a command of the new task", since=mark)
        mark = listen.mark()
        core.proc.send_signal(signal.SIGSTOP)
        try:
            # a zero Twist between two steps of the task is not the halt: wait until the host has
            # noticed the silent core (it then halts its robots and runs no step until it is back)
            t_end = time.monotonic() + 10
            while host.state == "up" and time.monotonic() < t_end:
                time.sleep(0.02)
            assert host.state != "up", "the host did not notice the silent core"
            stopped_at = listen.wait(is_zero, 5, "zero Twist after the core went silent",
                                     since=listen.mark())
            time.sleep(0.5)
            assert all(v == 0.0 and w == 0.0 for t, v, w in listen.got if t >= stopped_at[0]), \
                "the robot was commanded to move after the core was lost"
        finally:
            core.proc.send_signal(signal.SIGCONT)
    finally:
        host.stop()
        th.join(10)
        listen.close()
        if sim is not None:
            sim.stop()

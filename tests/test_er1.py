"""The ER1 driver against a fake robot control center (RCC) on loopback: the text commands
of the thesis's robots (``move 25 cm``, ``move 90 degrees``, ``stop``, ``events``/``move done``),
alone and driving a robot of a real core through a real robot host."""
from __future__ import annotations

import socket
import threading
import time

import pytest

from conftest import next_event_where, wait_robots
from robo_comp.client import resolve_core
from robo_comp.errors import UnavailableError
from robo_comp.robots.er1 import ER1Driver, RCCLink
from robo_comp.robots.host import RobotHost
from robo_comp.robots.steps import Move, Turn


class FakeRCC:
    """Accepts one connection; acknowledges each command with ``OK`` and, once ``events`` was
    asked for, reports ``move done`` ``delay`` seconds after each ``move`` (unless stopped)."""

    def __init__(self, delay: float = 0.05, fail_on: str | None = None) -> None:
        self.srv = socket.create_server(("127.0.0.1", 0))
        self.address = f"127.0.0.1:{self.srv.getsockname()[1]}"
        self.delay = delay
        self.fail_on = fail_on
        self.commands: list[str] = []
        self.running = True
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        conn, _ = self.srv.accept()
        conn.settimeout(0.01)
        events, due, buf = False, None, b""
        while self.running:
            try:
                chunk = conn.recv(4096)
                if not chunk:
                    break
                buf += chunk
            except socket.timeout:
                pass
            while b"\n" in buf:
                line, buf = buf.split(b"\n", 1)
                cmd = line.decode().strip()
                self.commands.append(cmd)
                if self.fail_on and cmd.startswith(self.fail_on):
                    conn.sendall(b"error: motor stalled\r\n")
                    continue
                conn.sendall(b"OK\r\n")
                if cmd == "events":
                    events = True
                elif cmd.startswith("move ") and events:
                    due = time.monotonic() + self.delay
                elif cmd == "stop":
                    due = None
            if due is not None and time.monotonic() >= due:
                conn.sendall(b"move done\r\n")
                due = None
        conn.close()

    def close(self) -> None:
        self.running = False
        self.thread.join(2)
        self.srv.close()


def run_step(driver: ER1Driver, step, timeout: float = 3.0) -> None:
    driver.begin(step)
    t_end = time.monotonic() + timeout
    while not driver.update(0.01):
        assert time.monotonic() < t_end, "the step did not finish"
        time.sleep(0.005)


def test_steps_become_rcc_commands_and_the_pose_is_dead_reckoned():
    rcc = FakeRCC()
    try:
        d = ER1Driver(RCCLink(rcc.address), cell_cm=25, x=0, y=0, heading=0)
        run_step(d, Move(1, 0))
        assert d.pose == (1.0, 0.0, 0.0)
        run_step(d, Move(1, 1))  # face +y (90 degrees, clockwise on the map), then one cell
        assert d.pose == (1.0, 1.0, 90.0) and d.cell() == (1, 1)
        run_step(d, Turn(-90))
        assert d.heading == 0.0
        assert rcc.commands[:5] == ["events", "move 25 cm", "move 90 degrees", "move 25 cm", "move -90 degrees"]
    finally:
        rcc.close()


def test_halt_sends_stop_at_once_and_errors_end_the_step_like_a_bump():
    rcc = FakeRCC(delay=5.0)
    try:
        d = ER1Driver(RCCLink(rcc.address), cell_cm=25, x=3, y=3, heading=0)
        d.begin(Move(4, 3))
        d.halt()
        assert not d.moving and d.pose == (3.0, 3.0, 0.0)
        t_end = time.monotonic() + 2
        while "stop" not in rcc.commands and time.monotonic() < t_end:
            time.sleep(0.01)
        assert rcc.commands[-2:] == ["move 25 cm", "stop"]
    finally:
        rcc.close()
    rcc = FakeRCC(fail_on="move")
    try:
        d = ER1Driver(RCCLink(rcc.address), cell_cm=25, x=0, y=0, heading=0)
        run_step(d, Move(1, 0))
        assert d.bump is not None and "motor stalled" in d.bump["error"]
    finally:
        rcc.close()
    with pytest.raises(UnavailableError, match="HOST:PORT"):
        RCCLink("nowhere")


def test_a_host_drives_an_er1_for_a_real_core(core):
    rcc = FakeRCC(delay=0.02)
    host = RobotHost(resolve_core(str(core.state)), core.host_token("red"), 1, driver="er1",
                     driver_options={"rcc": [rcc.address]})
    th = threading.Thread(target=host.run, kwargs={"duration": 30}, daemon=True)
    th.start()
    try:
        red = core.client("red")
        red.watch(True)
        row = wait_robots(red, 1)[0]
        x, y = round(row["x"]), round(row["y"])
        from robo_comp.protocol import unpack_walls

        walls = unpack_walls(red.arena())
        target = next((x + dx, y + dy) for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1))
                      if 0 <= x + dx < walls.shape[1] and 0 <= y + dy < walls.shape[0] and not walls[y + dy, x + dx])
        tid = red.give(row["tag"], "goTo", list(target))["task_id"]
        done = next_event_where(red, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == tid, 15)
        assert done["data"]["ok"], done["data"]
        assert any(c.endswith(" cm") for c in rcc.commands)
        m = red.monitor(row["tag"])
        assert (round(m["x"]), round(m["y"])) == target  # the dead-reckoned pose is what it reports
    finally:
        host.stop()
        th.join(5)
        rcc.close()

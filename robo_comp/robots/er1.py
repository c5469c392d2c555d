"""The ER1 driver: a real robot driven through its Robot Control Center's text commands.

The thesis's ER1 robots were driven by their Robot Control Center (RCC) over a telnet
connection with one-line commands: ``move 30 cm``, ``move -30 cm``, ``move 90 degrees``,
``stop``, and ``events`` to have the RCC report ``move done`` when a movement has finished
(thesis 2.2, 4.4.2). :class:`RCCLink` is that connection (non-blocking, polled from the
host's loop: no thread), :class:`ER1Driver` turns the host's steps into those commands.

A step ``Move(x, y)`` becomes a turn to face the cell (if needed) and a drive of one cell's
length; the driver waits for ``move done`` after each command. The ER1 has no positioning
system of its own: the pose is dead-reckoned from the commands that finished. ``halt`` sends
``stop`` at once; after a stop in the middle of a movement the pose is the last one known
(the thesis's reason to interrupt only at movement boundaries). An ``error`` line from the
RCC, or a lost connection, ends the step like a bump so the task fails with that message.
"""
from __future__ import annotations

import math
import socket
from typing import Any

from robo_comp.errors import UnavailableError
from robo_comp.robots.drivers import PoseReadings
from robo_comp.robots.steps import Move, Step, Turn

MAX_LINE = 4096


class RCCLink:
    """A line-based text connection to an RCC's command-line interface (``HOST:PORT``)."""

    def __init__(self, address: str, timeout: float = 3.0) -> None:
        host, _, port = address.rpartition(":")
        if not host or not port.isdigit():
            raise UnavailableError(f"--rcc {address!r}: give the robot control center as HOST:PORT")
        try:
            self.sock = socket.create_connection((host, int(port)), timeout)
        except OSError as e:
            raise UnavailableError(f"cannot reach the robot control center at {address}: {e}") from None
        self.sock.setblocking(False)
        self.address = address
        self.buf = b""
        self.closed = False

    def send(self, line: str) -> None:
        """Send one command line."""
        if self.closed:
            return
        try:
            self.sock.sendall((line + "\r\n").encode("ascii"))
        except BlockingIOError:  # the RCC's buffer is full: wait for it (rare: commands are short)
            self.sock.setblocking(True)
            try:
                self.sock.sendall((line + "\r\n").encode("ascii"))
            finally:
                self.sock.setblocking(False)
        except OSError:
            self.closed = True

    def lines(self) -> list[str]:
        """The complete lines received so far (without line ends), never blocking."""
        while not self.closed:
            try:
                chunk = self.sock.recv(4096)
            except BlockingIOError:
                break
            except OSError:
                self.closed = True
                break
            if not chunk:
                self.closed = True
                break
            self.buf += chunk
            if len(self.buf) > MAX_LINE * 16:
                self.buf = self.buf[-MAX_LINE:]
        *done, self.buf = self.buf.split(b"\n")
        return [d.decode("ascii", "replace").strip() for d in done if d.strip()]

    def close(self) -> None:
        """Close the connection."""
        self.closed = True
        self.sock.close()


class ER1Driver(PoseReadings):
    """One ER1 robot, commanded one step at a time through its RCC (same interface as
    :class:`robo_comp.robots.drivers.ArenaDriver`)."""

    def __init__(self, link: RCCLink, *, cell_cm: float, x: float, y: float, heading: float = 0.0) -> None:
        self.link = link
        self.cell_cm = float(cell_cm)
        self._pose = [float(x), float(y), float(heading)]
        self.step: Step | None = None
        self.bump: dict[str, Any] | None = None
        self._plan: list[tuple[str, tuple[float, float, float]]] = []  # (command, pose after it)
        self._sent = False
        self._timer = 0.0
        self.sent: list[str] = []  # every command sent (the host's log and tests read it)
        self._send("events")

    def _send(self, line: str) -> None:
        self.sent.append(line)
        self.link.send(line)

    # what the robot believes ----------------------------------------------------------
    @property
    def pose(self) -> tuple[float, float, float]:
        """Dead-reckoned (x, y, heading)."""
        return self._pose[0], self._pose[1], self._pose[2]

    def truth(self) -> tuple[float, float, float]:
        """A real robot's truth is not known here: the dead-reckoned pose."""
        return self.pose

    # commands ---------------------------------------------------------------------------
    def begin(self, step: Step) -> None:
        """Start ``step``: send its first command."""
        self.link.lines()  # a late "move done" of a stopped movement must not count for this step
        self.step = step
        self.bump = None
        self._plan = []
        self._sent = False
        x, y, h = self.pose
        if isinstance(step, Move):
            dx, dy = step.x - x, step.y - y
            face = math.degrees(math.atan2(dy, dx)) % 360.0
            turn = (face - h + 180.0) % 360.0 - 180.0
            if abs(turn) > 0.5:
                self._plan.append((f"move {turn:.0f} degrees", (x, y, face)))
            dist = math.hypot(dx, dy) * self.cell_cm
            self._plan.append((f"move {dist:.0f} cm", (float(step.x), float(step.y), face)))
        elif isinstance(step, Turn):
            self._plan.append((f"move {step.degrees:.0f} degrees", (x, y, (h + step.degrees) % 360.0)))
        else:
            self._start_timer(step)
        self._next()

    def _next(self) -> None:
        if self._plan:
            self._send(self._plan[0][0])
            self._sent = True

    def halt(self) -> None:
        """Stop at once (``stop``); the pose stays the last one known."""
        self._send("stop")
        self.step = None
        self._plan = []
        self._sent = False

    def update(self, dt: float) -> bool:
        """Read the RCC's answers; True when the current step finished (or failed like a bump)."""
        lines = self.link.lines()
        if self.step is None:
            return False
        for line in lines:
            low = line.lower()
            if low.startswith("move done") and self._sent and self._plan:
                _, after = self._plan.pop(0)
                self._pose = list(after)
                self._sent = False
                self._next()
            elif low.startswith("error"):
                return self._fail(f"the robot control center said {line!r}")
        if self.link.closed:
            return self._fail("the connection to the robot control center was lost")
        return self._step_ended(bool(self._plan), dt)

    def _fail(self, what: str) -> bool:
        self.bump = {"error": what, "x": self._pose[0], "y": self._pose[1]}
        self.step = None
        self._plan = []
        return True

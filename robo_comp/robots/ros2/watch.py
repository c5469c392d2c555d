"""Listening to a ROS 2 robot's ``cmd_vel`` as the robot does (for tests and benches): every
command that reaches the bus, with the time it arrived."""
from __future__ import annotations

import threading
import time
from collections.abc import Callable

from robo_comp.robots.ros2.bus import Bus, topic_name
from robo_comp.robots.ros2.msgs import Twist


class CommandWatch:
    """Takes every ``Twist`` published on ``/ns/cmd_vel`` (a reliable reader, a thread waiting on
    it) into :attr:`got` as ``(time.monotonic(), linear.x, angular.z)``."""

    def __init__(self, bus: Bus, ns: str) -> None:
        self.bus = bus
        self.got: list[tuple[float, float, float]] = []
        self.cond = threading.Condition()
        self.reader = bus.reader(topic_name(ns, "cmd_vel"), Twist, depth=1000, reliable=True)
        self.running = True
        self.thread = threading.Thread(target=self._run, name="cmd_vel-watch", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState, WaitSet
        from cyclonedds.util import duration

        ws = WaitSet(self.bus.participant)
        ws.attach(ReadCondition(self.reader, SampleState.Any | ViewState.Any | InstanceState.Any))
        while self.running:
            ws.wait(duration(milliseconds=50))
            msgs = self.reader.take(N=1000)
            now = time.monotonic()
            rows = [(now, m.linear.x, m.angular.z) for m in msgs if isinstance(m, Twist)]
            if rows:
                with self.cond:
                    self.got.extend(rows)
                    self.cond.notify_all()

    def mark(self) -> int:
        """Where the commands from now on start (for :meth:`wait`)."""
        with self.cond:
            return len(self.got)

    def wait(self, pred: Callable[[float, float], bool], timeout: float, what: str,
             since: int | None = None) -> tuple[float, float, float]:
        """The first command since ``since`` (a :meth:`mark`; default: from now on) for which
        ``pred(v, w)`` holds; AssertionError naming ``what`` after ``timeout`` seconds."""
        with self.cond:
            start = len(self.got) if since is None else since
            t_end = time.monotonic() + timeout
            while True:
                for row in self.got[start:]:
                    if pred(row[1], row[2]):
                        return row
                start = len(self.got)
                left = t_end - time.monotonic()
                if left <= 0:
                    raise AssertionError(f"no {what} on cmd_vel within {timeout} s")
                self.cond.wait(left)

    def close(self) -> None:
        """Stop taking."""
        self.running = False
        self.thread.join(1)


def is_zero(v: float, w: float) -> bool:
    """A stop command: no speed, no turn."""
    return v == 0.0 and w == 0.0

"""What each entrant of an engine match costs the machine, for the match limits of
:class:`robo_comp.engine.budget.Budget` (the league's compute, real-time and memory limits).

* **CPU** — the CPU time of the entrant's sandbox processes (its team's code and the child's
  own work), from the sandbox's own accounting (:meth:`Sandbox.cpu_seconds`): what the
  entrant's code costs, the same on an idle and on a loaded machine.
* **Real time** — the time the match waited for the entrant's code: a generous backstop only
  (it grows with the machine's load).
* **Memory** — the entrant's sandbox child's growth since the match started
  (:meth:`Sandbox.memory_mib`) plus the worker's growth while the engine served the entrant's
  robots. The engine is step-locked: while it serves a robot (starts its task or asks it for
  its next step: answers its calls, logs its events, waits for its code) it does nothing for
  anyone else, so the worker's new memory in that time is what that robot's calls and events
  took (a robot served inside another's span, a task started by another's end, is charged
  its own part). Growth while the simulation steps (all robots' movements at once) is no
  entrant's.
"""
from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from robo_comp.sandbox.parent import Sandbox

#: Real seconds of waiting for an entrant between two reads of its CPU time: the CPU used
#: since the last read can be at most about this much (its code only runs while the bench
#: waits for it), and a read (a few files of /proc) is not paid on every poll.
CPU_READ_EVERY = 0.25


_PAGE = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096
_statm: int | None = None


def rss_mib() -> float:
    """This process's resident memory in MiB (0 where /proc is not there). The file stays
    open: a read is then a few microseconds, cheap enough around every robot served."""
    global _statm
    try:
        if _statm is None:
            _statm = os.open("/proc/self/statm", os.O_RDONLY | os.O_CLOEXEC)
        return int(os.pread(_statm, 128, 0).split()[1]) * _PAGE / 2**20
    except (OSError, ValueError, IndexError):
        return 0.0


class EntrantMeter:
    """Per entrant (team) of an engine match: CPU seconds, real seconds waited and MiB of memory
    since :meth:`start` (see the module docstring). ``sandbox_of(team)`` is the team's sandbox,
    or None while it has none."""

    def __init__(self, teams: Iterable[str], sandbox_of: Callable[[str], Sandbox | None]) -> None:
        self.teams = list(teams)
        self.sandbox_of = sandbox_of
        self.waited: dict[str, float] = dict.fromkeys(self.teams, 0.0)
        self.cpu: dict[str, float] = dict.fromkeys(self.teams, 0.0)
        self.worker_mib: dict[str, float] = dict.fromkeys(self.teams, 0.0)
        self._cpu0: dict[str, float] = dict.fromkeys(self.teams, 0.0)
        self._child0: dict[str, float] = dict.fromkeys(self.teams, 0.0)
        self._unread: dict[str, float] = dict.fromkeys(self.teams, 0.0)
        self._spans: list[list[float]] = []  # the serving spans open now: [start RSS, growth inside]

    def _cpu_of(self, team: str) -> float:
        sb = self.sandbox_of(team)
        return 0.0 if sb is None else sb.cpu_seconds()

    def _child_of(self, team: str) -> float:
        sb = self.sandbox_of(team)
        return 0.0 if sb is None else sb.memory_mib()

    def start(self) -> None:
        """The match starts now (modules loaded): count from here."""
        for team in self.teams:
            self._cpu0[team] = self._cpu_of(team)
            self._child0[team] = self._child_of(team)
            self.waited[team] = self.cpu[team] = self.worker_mib[team] = self._unread[team] = 0.0

    def wait(self, team: str, seconds: float) -> float:
        """The bench waited ``seconds`` of real time for ``team``'s code; returns the team's CPU
        seconds so far (read again once it has been waited for :data:`CPU_READ_EVERY`)."""
        self.waited[team] += seconds
        self._unread[team] += seconds
        if self._unread[team] >= CPU_READ_EVERY:
            self.read_cpu(team)
        return self.cpu[team]

    def read_cpu(self, team: str) -> float:
        """``team``'s CPU seconds since the start, read now."""
        self._unread[team] = 0.0
        self.cpu[team] = max(0.0, self._cpu_of(team) - self._cpu0[team])
        return self.cpu[team]

    @contextmanager
    def serving(self, team: str | None) -> Iterator[None]:
        """Charge the worker's growth while the engine serves one of ``team``'s robots to it
        (None: to nobody), less the growth of spans served inside this one (charged to theirs);
        memory freed meanwhile is not credited (what the match keeps only grows)."""
        span = [rss_mib(), 0.0]
        self._spans.append(span)
        try:
            yield
        finally:
            self._spans.pop()
            grown = max(0.0, rss_mib() - span[0])
            if team in self.worker_mib:
                self.worker_mib[team] += max(0.0, grown - span[1])
            if self._spans:
                self._spans[-1][1] += grown

    def memory_mib(self, team: str) -> float:
        """``team``'s memory: its sandbox child's growth since the start (read now) plus the
        worker's growth while its robots were served."""
        child = max(0.0, self._child_of(team) - self._child0[team])
        return self.worker_mib[team] + child


__all__ = ["CPU_READ_EVERY", "EntrantMeter", "rss_mib"]

"""The match clock and its phases (:class:`~robo_comp.protocol.states.Phase`): setup → running ⇄ paused → finished.

Only the referee changes phases. The clock counts only while running; ``extend`` adds time.
The match asks :meth:`MatchClock.expired` every heartbeat and finishes the match at zero.

The clock is match time, kept on the driver's monotonic clock (the core's, or the engine's simulated one) and recorded in the event log
(with every phase change and every :data:`CLOCK_PERIOD` while running), never computed from
wall-clock stamps: a step of the machine's clock changes nothing. What an outage of the core
does to a running clock is the referee's :data:`OUTAGE_RULES` choice (default ``pause``).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

from robo_comp.errors import FieldError, PhaseError
from robo_comp.protocol.states import Phase

PHASES = tuple(Phase)
#: What a core outage (a crash, a restart) does to a running match clock: ``pause`` (the clock
#: stands still while no core runs: the default) or ``count`` (the outage is match time).
OUTAGE_RULES = ("pause", "count")
#: How often a running clock is recorded in the event log (``match.clock``): at most this much
#: running time is not recorded when the core is killed.
CLOCK_PERIOD = 0.25
ACTIONS = ("start", "pause", "resume", "finish", "extend")
# action -> (phases it is allowed from, phase it leads to)
_TRANSITIONS: dict[str, tuple[tuple[Phase, ...], Phase | None]] = {
    "start": ((Phase.SETUP,), Phase.RUNNING),
    "pause": ((Phase.RUNNING,), Phase.PAUSED),
    "resume": ((Phase.PAUSED,), Phase.RUNNING),
    "finish": ((Phase.SETUP, Phase.RUNNING, Phase.PAUSED), Phase.FINISHED),
    "extend": ((Phase.SETUP, Phase.RUNNING, Phase.PAUSED), None),
}


def _boot_id() -> str:
    try:
        with open("/proc/sys/kernel/random/boot_id") as f:
            return f.read().strip()
    except OSError:
        return ""


BOOT_ID = _boot_id()


def monotonic_mark() -> dict[str, Any]:
    """This machine's boot-time clock (it runs on while no core does and ignores steps of the
    wall clock) and its boot id: what the ``count`` outage rule measures an outage with."""
    return {"boot": round(time.clock_gettime(time.CLOCK_BOOTTIME), 3), "boot_id": BOOT_ID}


def outage_seconds(mark: dict[str, Any], wall_then: float) -> tuple[float, str]:
    """How long the core was down since ``mark`` (a :func:`monotonic_mark` logged at wall time
    ``wall_then``) and how that was measured: by the boot-time clock on the same boot, else by
    the wall clock (the only clock that spans a reboot)."""
    if mark.get("boot_id") and mark.get("boot_id") == BOOT_ID and "boot" in mark:
        return max(0.0, time.clock_gettime(time.CLOCK_BOOTTIME) - float(mark["boot"])), "the machine's boot-time clock"
    return max(0.0, time.time() - wall_then), "the wall clock (the machine was restarted since)"


@dataclass
class MatchClock:
    """The phase and the running time of one match; times are ``time.monotonic()`` seconds."""

    duration: float = math.inf
    phase: Phase = Phase.SETUP
    elapsed_before: float = 0.0
    running_since: float | None = None
    #: One of :data:`OUTAGE_RULES`.
    outage: str = "pause"

    def elapsed(self, now: float) -> float:
        """Seconds the match has been running."""
        return self.elapsed_before + (now - self.running_since if self.running_since is not None else 0.0)

    def remaining(self, now: float) -> float:
        """Seconds left (``inf`` for a match without a time limit)."""
        return max(0.0, self.duration - self.elapsed(now))

    def expired(self, now: float) -> bool:
        """True when a running match has used up its time (to a nanosecond: a simulated clock
        that adds up its steps ends a few ulps short of the match's length)."""
        return self.phase is Phase.RUNNING and self.remaining(now) <= 1e-9

    def apply(self, action: str, now: float, seconds: float | None = None) -> Phase:
        """Carry out a referee action; return the new phase or raise :class:`PhaseError`."""
        if action not in _TRANSITIONS:
            raise FieldError(f"unknown match action {action!r}; use one of {', '.join(ACTIONS)}")
        allowed, to = _TRANSITIONS[action]
        if self.phase not in allowed:
            raise PhaseError(f"cannot {action} the match while it is {self.phase}"
                             + (" (it is over; results are frozen)" if self.phase is Phase.FINISHED else ""))
        if action == "extend":
            if seconds is None or not (0 < seconds <= 24 * 3600):
                raise FieldError("extend needs 'seconds' between 0 and 86400")
            self.duration += seconds
            return self.phase
        if self.running_since is not None:  # leaving "running"
            self.elapsed_before = self.elapsed(now)
            self.running_since = None
        if to is Phase.RUNNING:
            self.running_since = now
        assert to is not None
        self.phase = to
        return to

    def set_outage(self, rule: Any) -> None:
        """Choose what a core outage does to the running clock (one of :data:`OUTAGE_RULES`)."""
        if rule not in OUTAGE_RULES:
            raise FieldError(f"the outage rule is 'pause' (the clock stands still while the core is down) "
                             f"or 'count' (the outage is match time), not {rule!r}")
        self.outage = rule

    def state(self, now: float) -> dict[str, Any]:
        """Phase and times as plain data (``remaining`` is nil without a time limit)."""
        rem = self.remaining(now)
        return {"phase": self.phase, "elapsed": round(self.elapsed(now), 3),
                "remaining": None if math.isinf(rem) else round(rem, 3),
                "duration": None if math.isinf(self.duration) else self.duration, "outage": self.outage}

    def restore(self, phase: str, elapsed: float, duration: float | None, now: float) -> None:
        """Set the clock from a logged state (recovery): a running match keeps running."""
        self.phase = Phase(phase)
        self.elapsed_before = elapsed
        self.duration = math.inf if duration is None else duration
        self.running_since = now if self.phase is Phase.RUNNING else None

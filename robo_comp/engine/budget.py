"""What one robot, and one entrant, may ask of a match on the engine: the call budget and the limits.

Every robot call that takes no time draws on the robot's **call budget**, a bucket of
``call_burst`` calls refilled at ``calls_per_second`` per *simulated* second (a picture costs
``picture_cost`` calls); a call the bucket cannot pay waits (in simulated time) until it can, so
code that never moves cannot hold up the clock, and code that floods (pictures between every two
moves) gets no more per simulated second than the budget. On a robot host every call takes real
time; this is its simulated price.

The other limits are per **entrant** (team) and per match; None: no limit. Going over one ends
the match as that entrant's forfeit (:class:`Forfeit`): ``events`` (events its robots caused),
``log_bytes`` (their size, as JSON lines), ``cpu_seconds`` (CPU time of its sandbox's
processes), ``wall_seconds`` (real time the match waited for its code: a backstop, it grows with
the machine's load) and ``memory_mib`` (its sandbox's growth plus this process's growth while its
robots were served); see :mod:`robo_comp.engine.usage`.
"""
from __future__ import annotations

from dataclasses import dataclass

#: Calls that take no time one robot may make at once (the call budget's burst).
CALL_BURST = 100
#: Robot calls that take a picture: each costs :attr:`Budget.picture_cost` calls of the budget.
PICTURE_CALLS = frozenset({"take_picture", "upload_picture", "look"})


@dataclass(frozen=True)
class Budget:
    """The call budget of each robot and the limits of each entrant (see the module docstring)."""

    calls_per_second: float = 10.0
    call_burst: float = CALL_BURST
    picture_cost: float = 4.0
    events: int | None = None
    log_bytes: int | None = None
    wall_seconds: float | None = None
    memory_mib: float | None = None
    cpu_seconds: float | None = None


@dataclass(frozen=True)
class Forfeit:
    """Why a match ended early: ``team`` went over ``limit`` (``events``, ``log_bytes``,
    ``cpu_seconds``, ``wall_seconds``, ``memory_mib``); ``message`` says it to the student; ``t`` is the
    simulated time."""

    team: str
    limit: str
    message: str
    t: float


class CallBuckets:
    """The call budget of every robot: :meth:`pay` returns how long a call waits for it."""

    def __init__(self, budget: Budget, dt: float) -> None:
        self.budget = budget
        self.dt = dt
        self._tokens: dict[int, tuple[float, float]] = {}  # tag -> (calls left, at simulated time)

    def pay(self, tag: int, name: str, now: float) -> float:
        """Draw call ``name``'s price from robot ``tag``'s bucket at simulated time ``now``;
        returns the simulated seconds it waits until it is paid (0: at once)."""
        b = self.budget
        cost = b.picture_cost if name in PICTURE_CALLS else 1.0
        left, at = self._tokens.get(tag, (float(b.call_burst), now))
        if b.calls_per_second > 0:
            left = min(float(b.call_burst), left + max(0.0, now - at) * b.calls_per_second)
        left -= cost
        wait = 0.0
        if left < 0:
            if b.calls_per_second <= 0:
                wait = self.dt  # no rate: one clock step per call over the burst
                left = 0.0
            else:
                wait = -left / b.calls_per_second
        self._tokens[tag] = (left, now) if wait == 0.0 else (0.0, now + wait)
        return wait


__all__ = ["Budget", "CALL_BURST", "CallBuckets", "Forfeit", "PICTURE_CALLS"]

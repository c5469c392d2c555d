"""Readings that follow the world: a standing robot's range readings are reported when they change.

A robot host reads a moving robot's sensors once a **sensing period** (``RobotHost.sensor_interval``,
0.5 s by default, ``robots --sensor-hz``) and reports a standing robot's pose once a second. What a
standing robot's range sensors see changes too: another robot (one of this host's, another host's
simulated one, or a real one the overhead camera tracks, :mod:`robo_comp.robots.oneworld`) drives
into its beams or out of them. So at every report tick the host samples its standing robots' ranges
in one vectorised pass (:meth:`robo_comp.world.arena.Arena.sense_all`, no rows built) and reports a
robot whose ranges moved beyond the sensor noise since it last reported them.

Bounded: a robot's changed readings are reported at most once a sensing period, so a host of 1,000
standing robots in a busy arena adds at most 1,000 rows a sensing period to its once-a-second pose
reports (fewer rows than 1,000 moving robots send), and a quiet arena adds nothing. A change is
reported at the next report tick (0.1 s) after the body is in this host's arena, or, when the
robot's readings changed within the last sensing period already, once that period is over.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np

from robo_comp.robots.oneworld import is_real, merge_readings
from robo_comp.world.arena import Arena

#: The ranges compared, in the order of :class:`robo_comp.world.sensors.RangeReadings`.
RANGES = ("front", "left", "right", "down")
#: A range moved when it changed by more than this many σ of the sensor noise (two noisy samples of
#: the same distance differ by more than 8σ about once in 65 million comparisons; 8 cm at the default
#: σ of 1 cm, a third of a 25 cm cell)...
NOISE_SIGMAS = 8.0
#: ... and at least this many cm.
MIN_CHANGE_CM = 1.0


class Watched(Protocol):
    """What the watch needs of a hosted robot: its id in the arena and its driver."""

    robot_id: str
    driver: Any


class ReadingWatch:
    """Which standing robots' range readings changed since they were last reported.

    The host tells it every readings row it sends (:meth:`sent`) and asks it each report tick
    which of the robots it would not report anyway have changed (:meth:`changed`)."""

    def __init__(self, period: float) -> None:
        #: The sensing period: a robot's changed readings are reported at most once in it.
        self.period = period
        self._sent: dict[str, tuple[float, ...]] = {}  # robot id -> ranges last reported (cm; nan: no echo)
        self._changed_at: dict[str, float] = {}  # robot id -> when a change of it was last reported

    @staticmethod
    def _ranges(readings: dict[str, Any]) -> tuple[float, ...]:
        """A readings row's ranges in cm (nan: no echo)."""
        return tuple(np.nan if readings.get(k) is None else float(readings[k]) for k in RANGES)

    def sent(self, robot_id: str, readings: dict[str, Any]) -> None:
        """Robot ``robot_id``'s readings went out in a report (on any path)."""
        self._sent[robot_id] = self._ranges(readings)

    def changed(self, world: Arena | None, robots: Sequence[Watched], now: float) -> list[Any]:
        """Of ``robots`` (standing robots the host does not report this tick anyway), those whose
        ranges moved beyond the noise since they were last reported and whose last reported change
        is a sensing period old; they count as reported now. A robot that never sent readings is
        left to its next periodic report."""
        if world is None or not robots:
            return []
        cand = [r for r in robots if r.robot_id in self._sent
                and not 0.0 <= now - self._changed_at.get(r.robot_id, -np.inf) < self.period]  # (a clock gone back too)
        if not cand:
            return []
        cfg = world.scenario.sensors
        _, rr = world.sense_all([r.robot_id for r in cand])
        seen = np.stack([rr.front, rr.left, rr.right, rr.down], axis=1)
        for i, r in enumerate(cand):  # a real robot's readings are the nearer of its own and the virtual world's
            own = getattr(r.driver, "readings", None) if is_real(r.driver) else None
            if own is not None:
                seen[i] = self._ranges(merge_readings(rr.row(i), own()))
        before = np.array([self._sent[r.robot_id] for r in cand], dtype=np.float64)
        # no echo counts as the maximum range: a wall just at the edge of the range, whose echo comes
        # and goes with the noise, is no change
        seen = np.where(np.isnan(seen), cfg.max_range, seen)
        before = np.where(np.isnan(before), cfg.max_range, before)
        moved = np.any(np.abs(seen - before) > max(MIN_CHANGE_CM, NOISE_SIGMAS * cfg.noise), axis=1)
        out = [r for r, m in zip(cand, moved) if m]
        for r in out:
            self._changed_at[r.robot_id] = now
        return out

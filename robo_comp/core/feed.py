"""The robots' poses on the core's feeds: conflated batches live, samples in the log.

However often robots report, the live feed carries at most one ``robot.positions`` batch per
team per pose period (the newest pose of each robot that reported), and the log one sample per
robot per heartbeat. Both are cut into chunks of at most :data:`POSE_CHUNK` robots, queued as
slices of background work: the core's loop does one slice per turn and looks at its socket in
between, so that a stop never waits behind a whole batch of 10,000 robots.
"""
from __future__ import annotations

from collections import deque
from collections.abc import Callable
from functools import partial
from typing import Any

from robo_comp.match.model import Match

#: Robots per ``robot.positions`` event (and per logged sample record).
POSE_CHUNK = 500


class PositionFeed:
    """Queues the position batches (``emit``) and samples (``log``) as slices of background work."""

    def __init__(self, match: Match, emit: Callable[..., None], log: Callable[[list[int]], None],
                 slices: deque[Callable[[], None]]) -> None:
        self.match = match
        self.emit = emit
        self.log = log
        self.slices = slices

    def queue(self) -> None:
        """Queue the newest pose of every robot that reported since the last batch, per team."""
        posed, self.match.posed = self.match.posed, {}
        for team in sorted(posed):
            tags = sorted(posed[team])
            for k in range(0, len(tags), POSE_CHUNK):
                self.slices.append(partial(self._publish, team, tags[k:k + POSE_CHUNK]))

    def _publish(self, team: str, tags: list[int]) -> None:
        """One ``robot.positions`` event (feed only) for robots ``tags`` of ``team``. A robot lost or
        gone since it reported is left out: its ``robot.lost``/``robot.left`` went first."""
        batch: dict[str, Any] | None = self.match.position_batch(team, tags)
        if batch is not None:
            self.emit("robot.positions", team, batch, log_it=False)

    def publish_now(self) -> None:
        """Publish every robot that reported since the last batch now (a replay's step)."""
        self.queue()
        while self.slices:
            self.slices.popleft()()

    def sample(self) -> None:
        """Queue the robots that moved since the last heartbeat for the log, in chunks."""
        moved = self.match.moved
        if not moved:
            return
        tags = sorted(moved)
        moved.clear()
        for k in range(0, len(tags), POSE_CHUNK):
            self.slices.append(partial(self.log, tags[k:k + POSE_CHUNK]))


__all__ = ["POSE_CHUNK", "PositionFeed"]

"""The match clock as a client heard it: consoles and walls run it on between two messages."""
from __future__ import annotations

from dataclasses import dataclass

from robo_comp.protocol.states import Phase


@dataclass
class HeardClock:
    """The match clock as a console or a wall last heard it (``match.phase``, ``score``), with
    the local monotonic time it was heard: :meth:`now` runs it on while the match runs."""

    phase: str = ""
    elapsed: float = 0.0
    remaining: float | None = None
    heard_at: float | None = None

    def now(self, at: float | None) -> tuple[float, float | None]:
        """``(elapsed, remaining)`` extrapolated to local time ``at`` while running (``at`` None:
        as heard)."""
        if at is None or self.heard_at is None or self.phase != Phase.RUNNING:
            return self.elapsed, self.remaining
        d = max(0.0, at - self.heard_at)
        return self.elapsed + d, None if self.remaining is None else max(0.0, self.remaining - d)


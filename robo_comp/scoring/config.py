"""Scoring settings of a match (the ``[scoring]`` table of a scenario, or these defaults)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class ScoringConfig:
    """Points and penalties of the default search-and-rescue rules.

    ``victim_points`` by victim kind (a victim's own ``points`` in the scenario wins);
    ``first_bonus`` to the first team that reports a victim; ``false_report`` for a find
    that matches no victim, lacks evidence or was not examined; ``collision`` per bump;
    ``robot_lost`` per robot lost; ``match_radius`` in cells between a report and a victim.
    """

    victim_points: dict[str, float] = field(default_factory=lambda: {"adult": 10.0, "child": 15.0,
                                                                      "injured": 20.0})
    default_points: float = 10.0
    first_bonus: float = 5.0
    false_report: float = -5.0
    collision: float = -1.0
    robot_lost: float = -2.0
    match_radius: float = 1.5
    rules: str = "sar"

    @classmethod
    def from_table(cls, table: dict[str, Any]) -> "ScoringConfig":
        """The defaults with a scenario's ``[scoring]`` table applied (``victim_points`` merge)."""
        base = cls()
        points = dict(base.victim_points, **table.get("victim_points", {}))
        others = {k: v for k, v in table.items() if k != "victim_points"}
        return cls(victim_points=points, **others)

    def points_for(self, kind: str, own: float | None) -> float:
        """Points for a victim of ``kind`` (its own ``points`` win when set)."""
        return float(own) if own is not None else float(self.victim_points.get(kind, self.default_points))

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (shown to teams so the rules are known)."""
        return {"victim_points": dict(self.victim_points), "default_points": self.default_points,
                "first_bonus": self.first_bonus, "false_report": self.false_report,
                "collision": self.collision, "robot_lost": self.robot_lost,
                "match_radius": self.match_radius, "rules": self.rules}

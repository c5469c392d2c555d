"""Task lists for the bench: what a team gives its robots, written down ahead (the explorer's sweep)."""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Protocol

#: A task for :meth:`Bench.run_match`: ``(name, args)``.
TaskStep = tuple[str, "list[Any] | tuple[Any, ...]"]


class Bench(Protocol):
    """What a plan reads of a :class:`robo_comp.engine.bench.Bench`: the map, the robots, the pictures."""

    arena: Any
    team: str
    tags_of: dict[str, list[int]]

    @property
    def pictures(self) -> dict[int, dict[str, Any]]:
        """Every picture taken."""


def sweep_plan(bench: Bench, spacing: int = 6, task: str = "explore") -> dict[int, list[TaskStep]]:
    """A plan that covers the map with the template's explorer: the free cells of a grid of
    ``spacing`` cells, in serpentine row order, cut into one band per robot; each cell is one
    ``explore([[x, y]])`` task. Uses the map only (what every team knows)."""
    walls = bench.arena.walls
    tags = bench.tags_of[bench.team]
    h, w = walls.shape
    rows: list[list[int]] = []
    for i, y in enumerate(range(spacing // 2, h, spacing)):
        xs = [x for x in range(spacing // 2, w, spacing) if not walls[y, x]]
        rows.extend([x, y] for x in (xs if i % 2 == 0 else xs[::-1]))
    n = len(tags)
    size = max(1, math.ceil(len(rows) / n))
    return {tag: [(task, [[p]]) for p in rows[i * size:(i + 1) * size]] for i, tag in enumerate(tags)}


def report_seen(bench: Bench, task: str = "report_victim") -> Callable[[int, dict[str, Any]], list[TaskStep]]:
    """An ``on_done`` for :meth:`Bench.run_match`: after an ``explore`` whose pictures show a
    victim the team has not reported yet, report it (``report_victim(x, y, kind)``) next.

    It stands in for the team member who looks at the pictures on the team console: it reads
    what the simulated camera saw (``bench.pictures``), as a person reads the image.
    """
    reported: set[str] = set()
    victims = {v.id: v for v in bench.arena.victims}

    def on_done(tag: int, outcome: dict[str, Any]) -> list[TaskStep]:
        result = outcome.get("result")
        if not outcome["ok"] or not isinstance(result, dict):
            return []
        out: list[TaskStep] = []
        for pid in result.get("pictures", []):
            for vid in bench.pictures.get(pid, {}).get("victims", []):
                if vid not in reported:
                    reported.add(vid)
                    v = victims[vid]
                    out.append((task, [int(v.x), int(v.y), v.kind]))
        return out

    return on_done


__all__ = ["TaskStep", "report_seen", "sweep_plan"]

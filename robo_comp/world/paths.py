"""What the planners share: cells, the result of a query, and the compiled kernels (loaded on first use)."""
from __future__ import annotations

from dataclasses import dataclass
from types import ModuleType

Cell = tuple[int, int]

_kernels: ModuleType | None = None


def kernels() -> ModuleType:
    """The compiled kernel module (:mod:`robo_comp.world._kernels`), imported on first use."""
    global _kernels
    if _kernels is None:
        from robo_comp.world import _kernels as mod

        _kernels = mod
    return _kernels


@dataclass
class PathResult:
    """Outcome of one query: ``path`` (cells start..goal) and ``cost`` are None when there is
    no path; ``expanded`` counts the A* nodes expanded (0 when connectivity answered)."""

    path: list[Cell] | None
    cost: float | None
    expanded: int = 0

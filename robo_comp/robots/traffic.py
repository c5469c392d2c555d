"""Teammates keep out of each other's way: which cells a robot holds, who holds a cell, and who
makes way when two robots wait for each other.

The task runtime (:mod:`robo_comp.robots.runtime`) asks before every move. A robot holds the cell
it stands in, and during a move the cell it leaves and the cell it drives to (:func:`claim`); a
robot never drives into a cell a teammate holds (:func:`holder`): it waits. Two robots that wait
for each other's cells (head-on in a corridor) would wait for ever: one of them *makes way*
(:func:`make_way`): it drives to the nearest cell off the other's path (its *refuge*: a niche, a
side corridor, back the way it came), waits there until the other has passed, and plans again.
Both decide alike from what they both see, so exactly one of them makes way: the one whose
refuge is nearer, the higher tag when they are as near.

"Teammates" are the robots that run on the same robot host (on the engine: the same team); a
host sees other hosts' robots only through the camera (:mod:`robo_comp.robots.oneworld`).
"""
from __future__ import annotations

from collections import deque
from collections.abc import Iterable
from typing import Any, Protocol

Cell = tuple[int, int]


class SimRobot(Protocol):
    """A robot as traffic sees it (a :class:`robo_comp.robots.runtime.SimRobot`): its tag, its
    running task (``held``, ``path``, ``leaving``, ``to``), its host (``robots``, ``blocked``)."""

    tag: int
    robot_id: str
    task: Any
    host: Any
    driver: Any

    def cell(self) -> Cell:
        """The cell the robot believes it is in."""
#: How far (cells, as the robot drives) a refuge may be.
REFUGE_DEPTH = 40


def claim(r: SimRobot) -> tuple[Cell, ...]:
    """The cells robot ``r`` holds: the one it stands in, or, during a move, the one it leaves and
    the one it drives to, and, for a robot that may end a move a little long (one that drives
    freely, not cell by cell on a grid), the cell beyond (a teammate entering it meanwhile would be
    touched)."""
    t = r.task
    if t is not None and t.to is not None and t.leaving is not None:
        if getattr(r.driver, "grid_exact", False):
            return t.leaving, t.to
        beyond = (2 * t.to[0] - t.leaving[0], 2 * t.to[1] - t.leaving[1])
        return t.leaving, t.to, beyond
    return (r.cell(),)


def holder(r: SimRobot, cell: Cell) -> SimRobot | None:
    """The teammate of ``r`` that holds ``cell``, if one does."""
    for o in r.host.robots.values():
        if o is not r and cell in claim(o):
            return o
    return None


def held(r: SimRobot) -> set[Cell]:
    """Every cell a teammate of ``r`` holds now (what :func:`holder` looks through, for a search
    that asks about many cells at one instant)."""
    return {c for o in r.host.robots.values() if o is not r for c in claim(o)}


def crossing(r: SimRobot, cell: Cell) -> SimRobot | None:
    """For a robot that may end a move a little long: the teammate that is driving into the cell
    beyond ``cell`` (as seen from ``r``) or holds it as its own cell beyond, if one does. (A teammate
    standing there its front sensor sees, and it stops short; one arriving during the move it
    would not.)"""
    if getattr(r.driver, "grid_exact", False):
        return None
    here = r.cell()
    beyond = (2 * cell[0] - here[0], 2 * cell[1] - here[1])
    for o in r.host.robots.values():
        t = o.task
        if o is not r and t is not None and t.to is not None and beyond in claim(o)[1:]:
            return o
    return None


def wants(r: SimRobot) -> set[Cell]:
    """The cells robot ``r`` is still to drive through: its move waiting for a cell, and the rest of
    its task's planned path from where it is (unknown for team code's own moves)."""
    t = r.task
    out: set[Cell] = set()
    if t is None:
        return out
    if t.held is not None:
        out.add((t.held.x, t.held.y))
    path = t.path
    if path:
        here = r.cell()
        start = path.index(here) if here in path else 0
        out.update(path[start:])
    return out


def refuge(r: SimRobot, other: SimRobot) -> list[Cell] | None:
    """The cells ``r`` drives through to the nearest cell off ``other``'s way (its refuge, last),
    around walls, the team's obstacles and teammates; None when there is none within
    :data:`REFUGE_DEPTH`."""
    avoid = wants(other) | set(claim(other))
    taken = held(r)  # one look at the teammates, not one per cell searched
    blocked = r.host.blocked
    h, w = blocked.shape
    start = r.cell()
    came: dict[Cell, Cell | None] = {start: None}
    todo: deque[tuple[Cell, int]] = deque([(start, 0)])
    while todo:
        c, depth = todo.popleft()
        if c not in avoid and c != start:
            path = [c]
            back = came[c]
            while back is not None and back != start:
                path.append(back)
                back = came[back]
            return path[::-1]
        if depth >= REFUGE_DEPTH:
            continue
        x, y = c
        for n in ((x + 1, y), (x - 1, y), (x, y + 1), (x, y - 1)):
            if (n not in came and 0 <= n[0] < w and 0 <= n[1] < h and not blocked[n[1], n[0]]
                    and n not in taken):
                came[n] = c
                todo.append((n, depth + 1))
    return None


def make_way(r: SimRobot, other: SimRobot) -> list[Cell] | None:
    """Robot ``r`` and ``other`` wait for each other's cells: ``r``'s way to its refuge when ``r``
    is the one to make way, else None (``other`` makes way, or neither can)."""
    mine = refuge(r, other)
    if mine is None:
        return None
    theirs = refuge(other, r)
    if theirs is None or (len(mine), -r.tag) < (len(theirs), -other.tag):
        return mine
    return None


def passed(other: SimRobot | None, cells: Iterable[Cell]) -> bool:
    """Whether ``other`` has passed ``cells`` (it no longer means to drive through any of them)."""
    if other is None or other.task is None:
        return True
    return not (wants(other) & set(cells))


__all__ = ["REFUGE_DEPTH", "SimRobot", "claim", "crossing", "held", "holder", "make_way", "passed", "refuge", "wants"]

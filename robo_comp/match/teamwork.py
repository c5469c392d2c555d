"""A team's robots working for each other: a lost robot's work goes to a teammate, and the
obstacles one robot reports are on every teammate's map.

**Work survives a lost robot.** When a robot is lost (its host went silent, said bye, or the
referee handed it over) or leaves, its running, pending and queued tasks are *offered* to its
team: a ``task.offered`` event (the team's consoles show it), and the plugins' hook
``robo_comp_tasks_offered`` (``robo_comp.plugins.hookspecs``), which may hand each task to a
teammate of its choice. A team that turned on the built-in *reallocation* (the ``teamwork``
request, ``robo-comp ctl teamwork on``) has every task no plugin took moved to the nearest idle
teammate that advertises it (none idle: the nearest with the least work). A moved task is
cancelled on the lost robot ("moved to robot N") and given to the teammate, queued, as a new
task whose ``task.given`` names where it came from (``from``: tag and task id); an idle teammate
starts it at once, in the same turn as the loss. Without reallocation and without a plugin the
tasks stay with the lost robot and wait for it to return, as before.

**Obstacles.** A robot reports a cell its sensors see blocked that the map shows free (the
runtime does for the built-in tasks, team code calls ``robot.report_obstacle``): the match keeps
it for the robot's team (``map.obstacle``), the core's map service puts it on the team's map (a
``map.delta`` to the team's robot hosts) and every planner of the team routes around it.

The same happens live (the core drives the match) and on the engine (the bench drives it).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Any

from robo_comp.errors import FieldError, ImplausibleError, RoboCompError, TooLargeError
from robo_comp.match.output import MatchOutput
from robo_comp.match.registry import Registry, RobotRecord
from robo_comp.match.tasks import TaskMachine, TaskRecord
from robo_comp.protocol.states import RobotStatus, TaskState

#: How far (cells) from where the match tracks a robot an obstacle it reports may be: what its
#: sensors reach (a robot reports the cell it was about to drive into).
OBSTACLE_REACH = 3.0
#: Obstacles a team may report in a match (a bound on the map service's memory, not a rule of play).
MAX_OBSTACLES = 4096

#: ``give(robot, name, args, by, moved_from)``: the match's ``give`` of a queued task.
Give = Callable[[RobotRecord, str, list[Any], str, dict[str, Any]], Any]


class TeamWork:
    """The teams' reallocation settings and reported obstacles, and what follows a lost robot.

    It gets what it needs of the match explicitly: the registry, the task machine, the output
    (events), the plugin manager (the ``robo_comp_tasks_offered`` hook), the match's ``give`` and
    whether a robot was disqualified."""

    def __init__(self, registry: Registry, tasks: TaskMachine, out: MatchOutput, pm: Any, give: Give,
                 is_disqualified: Callable[[int], bool]) -> None:
        self.registry = registry
        self.tasks = tasks
        self.out = out
        self.pm = pm
        self.give = give
        self.is_disqualified = is_disqualified
        #: team -> whether its lost robots' tasks move to teammates by themselves.
        self.reallocate: dict[str, bool] = {}
        #: team -> the cells its robots reported blocked, with the tag that reported each.
        self.obstacles: dict[str, dict[tuple[int, int], int]] = {}

    # ------------------------------------------------------------------ a lost robot's work
    def set_reallocate(self, team: str, on: bool, by: str) -> dict[str, Any]:
        """Turn ``team``'s built-in reallocation on or off (``teamwork`` event); turned on, the
        tasks of its robots lost before are offered and moved now. Returns the ``teamwork`` reply."""
        self.reallocate[team] = bool(on)
        self.out.emit("teamwork", team, {"team": team, "reallocate": bool(on), "by": by})
        moved: list[int] = []
        if on:
            for r in self.registry.of_team(team):
                if r.status in (RobotStatus.LOST, RobotStatus.LEFT):
                    moved += self.robot_gone(r, "lost before reallocation was turned on")
        return {"team": team, "reallocate": bool(on), "moved": moved}

    def robot_gone(self, r: RobotRecord, why: str) -> list[int]:
        """Robot ``r`` was lost or left: offer its tasks to its team, move those a plugin or the
        built-in reallocation gives a teammate. Returns the ids of the new tasks."""
        waiting = [t for t in (r.current, r.pending, *r.queue) if t is not None]
        if not waiting or self.is_disqualified(r.tag):
            return []
        mates = [m for m in self.registry.of_team(r.team)
                 if m.tag != r.tag and m.status is RobotStatus.CONNECTED and not self.is_disqualified(m.tag)]
        offered = [{"task_id": t.id, "name": t.name, "args": t.args, "state": str(t.state)} for t in waiting]
        chosen = self._plugins_choose(r, offered, mates)
        on = self.reallocate.get(r.team, False)
        if on:
            load = {m.tag: _work(m) for m in mates}
            for t in waiting:
                if t.id not in chosen:
                    mate = self._nearest(r, t, mates, load)
                    if mate is not None:
                        chosen[t.id] = mate
                        load[mate.tag] += 1
        self.out.emit("task.offered", r.team, {
            "tag": r.tag, "team": r.team, "message": why, "reallocate": on,
            "tasks": [dict(o, to=chosen[o["task_id"]].tag if o["task_id"] in chosen else None) for o in offered]})
        moved = []
        for t in waiting:
            mate = chosen.get(t.id)
            if mate is not None:
                new = self._move(r, t, mate, why)
                if new is not None:
                    moved.append(new)
        return moved

    def _plugins_choose(self, r: RobotRecord, offered: list[dict[str, Any]],
                        mates: list[RobotRecord]) -> dict[int, RobotRecord]:
        """What the plugins' ``robo_comp_tasks_offered`` hands to which teammate (the first answer
        for a task counts; a teammate that is not connected or does not advertise the task is passed
        over)."""
        hook = getattr(getattr(self.pm, "hook", None), "robo_comp_tasks_offered", None)
        if hook is None or not hook.get_hookimpls():
            return {}
        by_tag = {m.tag: m for m in mates}
        names = {o["task_id"]: o["name"] for o in offered}
        chosen: dict[int, RobotRecord] = {}
        answers = hook(team=r.team, tag=r.tag, tasks=[dict(o) for o in offered], teammates=[m.summary() for m in mates])
        for answer in answers:
            for a in answer or ():
                if not isinstance(a, dict):
                    continue
                tid, mate = a.get("task_id"), a.get("tag")
                to = by_tag.get(mate) if type(mate) is int else None
                if type(tid) is int and tid in names and tid not in chosen and to is not None and names[tid] in to.tasks:
                    chosen[tid] = to
        return chosen

    @staticmethod
    def _nearest(r: RobotRecord, t: TaskRecord, mates: list[RobotRecord], load: dict[int, int]) -> RobotRecord | None:
        """The teammate for task ``t`` of ``r``: among those that advertise it, the idle ones first,
        then the least work, then the nearest to where ``r`` was (then the lowest tag)."""
        able = [m for m in mates if t.name in m.tasks]
        if not able:
            return None
        return min(able, key=lambda m: (load[m.tag], math.hypot(m.x - r.x, m.y - r.y), m.tag))

    def _move(self, r: RobotRecord, t: TaskRecord, mate: RobotRecord, why: str) -> int | None:
        """Give ``t`` to ``mate`` (queued), then cancel it on ``r``; None when ``mate`` would not
        take it (the match is paused, the arguments do not fit its advert): ``r`` keeps it."""
        try:
            reply = self.give(mate, t.name, list(t.args), f"teamwork:{r.tag}", {"tag": r.tag, "task_id": t.id})
        except RoboCompError:
            return None
        self.tasks.finish(r, t, False, f"moved to robot {mate.tag} (task {reply['task_id']}): robot {r.tag} {why}",
                          state=TaskState.CANCELLED)
        return int(reply["task_id"])

    # ------------------------------------------------------------------ obstacles
    def obstacle(self, r: RobotRecord, x: Any, y: Any, walls: Any) -> bool:
        """Robot ``r`` reports cell ``(x, y)`` blocked where the map (``walls``) shows it free: kept
        for its team (``map.obstacle``). A cell that is a wall on the map, outside it, or farther
        from the robot than its sensors reach is refused with a sentence; returns False for a cell
        the team knew already."""
        if type(x) is not int or type(y) is not int:
            raise FieldError("an obstacle is a cell: 'x' and 'y' must be whole numbers")
        h, w = walls.shape
        if not (0 <= x < w and 0 <= y < h):
            raise FieldError(f"({x}, {y}) is outside the {w}x{h} map")
        if walls[y, x]:
            raise FieldError(f"({x}, {y}) is a wall on the map already; report only what the map does not show")
        if math.hypot(x - r.x, y - r.y) > OBSTACLE_REACH:
            raise ImplausibleError(f"robot {r.tag} is tracked at ({r.x:.1f}, {r.y:.1f}); ({x}, {y}) is farther than "
                                   f"its sensors reach ({OBSTACLE_REACH:g} cells): report what is next to it")
        known = self.obstacles.setdefault(r.team, {})
        if (x, y) in known:
            return False
        if len(known) >= MAX_OBSTACLES:
            raise TooLargeError(f"team {r.team} has reported {MAX_OBSTACLES} obstacles, the most a match keeps")
        known[(x, y)] = r.tag
        self.out.emit("map.obstacle", r.team, {"tag": r.tag, "team": r.team, "x": x, "y": y})
        return True

    def cells(self, team: str | None) -> Iterable[tuple[str, tuple[int, int]]]:
        """``(team, cell)`` of every obstacle ``team`` knows (None: every team's)."""
        for name, known in self.obstacles.items():
            if team is None or name == team:
                for cell in known:
                    yield name, cell


def _work(r: RobotRecord) -> int:
    """How many tasks ``r`` has (running, pending, queued)."""
    return (r.current is not None) + (r.pending is not None) + len(r.queue)


__all__ = ["MAX_OBSTACLES", "OBSTACLE_REACH", "TeamWork"]

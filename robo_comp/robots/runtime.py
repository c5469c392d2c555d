"""The task runtime: how a robot runs its tasks, the same on a robot host and on the engine.

A task is a generator of steps (:mod:`robo_comp.robots.steps`). :class:`TaskRuntime` runs one per
robot: it asks the generator for a step, hands movements to the robot's driver, plans paths
(:class:`~robo_comp.robots.steps.Plan`), takes pictures (:class:`~robo_comp.robots.steps.Capture`),
lets team code compute (:class:`~robo_comp.robots.steps.Compute`), switches to a task given "now"
at the next movement boundary (an *interrupt*), ends a task a bump stopped, and reports the end.

It does this through a :class:`RuntimeEnv`, which is what differs between its two drivers:

* a robot host (:class:`robo_comp.robots.host.RobotHost`) plans in a thread, uploads pictures to
  the core, reports a task's end to the core and waits for a tick while team code computes;
* the engine (:class:`robo_comp.engine.bench.Bench`) plans at once, gives pictures and ends to
  the match in the same process, and waits for team code with its simulated clock stopped.

Both take their tasks from the match (``task.start``, ``task.interrupt``), so a task runs the
same steps, with the same checks and the same outcome, wherever the match is played.
"""
from __future__ import annotations

import logging
from collections import deque
from concurrent.futures import Future
from dataclasses import dataclass, field
from typing import Any, Protocol

from robo_comp.errors import RoboCompError
from robo_comp.protocol.taskspec import check_args
from robo_comp.robots.steps import Answer, Capture, CellPath, Compute, Plan, TaskFailed, TaskRun, TaskSpec, no_steps
from robo_comp.robots.teamcode import free_cell, in_bounds, stop_status
from robo_comp.world.planner import find_path

log = logging.getLogger("robo_comp.robots")

#: What :meth:`RuntimeEnv.plan` returns while the path is being found elsewhere.
PLANNING = object()


@dataclass(slots=True)
class RunningTask:
    """A task a robot is running: its id, name and generator of steps (and, while it waits for
    one, the path being planned off the loop; what comes back is sent into the generator)."""

    id: int
    name: str
    gen: TaskRun
    pictures: list[int] = field(default_factory=list)
    plan: Future[CellPath | None] | None = None
    answer: Answer = None


def plan_around(walls: Any, start: tuple[int, int], goal: tuple[int, int],
                occupied: set[tuple[int, int]]) -> list[tuple[int, int]] | None:
    """A path from ``start`` to ``goal`` around the ``occupied`` cells, straight through them when
    there is no way around (None: no path at all). Pure: a host runs it in its planner thread."""
    occupied = occupied - {start, goal}
    if occupied:
        blocked = walls.copy()
        h, w = blocked.shape
        for x, y in occupied:
            if 0 <= x < w and 0 <= y < h:
                blocked[y, x] = True
        path = find_path(blocked, start, goal)
        if path is not None:
            return path
    return find_path(walls, start, goal)


class RobotWorld(Protocol):
    """What a robot sees of the place that runs it (a robot host, or the engine)."""

    walls: Any  # the arena's wall grid [y, x]
    robots: dict[str, Any]  # robot id -> every robot run here (a SimRobot)
    world: Any  # the simulated arena (None until known)
    foreign: Any  # other hosts' robots the camera tracks (robo_comp.robots.oneworld.Foreign)


@dataclass(slots=True)
class SimRobot:
    """One robot run here: its driver, its tag, the task it runs and the one waiting for the next
    movement boundary. It is the :class:`~robo_comp.robots.steps.RobotView` its tasks see."""

    robot_id: str
    driver: Any  # ArenaDriver, an ER1's, a ROS 2 robot's: begin, halt, update, bump, pose, moving
    host: RobotWorld
    tag: int = 0
    task: RunningTask | None = None
    pending: dict[str, Any] | None = None  # a task given "now" that waits for the movement boundary
    inbox: deque[dict[str, Any]] = field(default_factory=lambda: deque(maxlen=100))
    last_report: float = 0.0
    last_sensed: float = 0.0
    #: Its camera fixes' track (which knows the fix taken last): a fix that the robot could not have
    #: driven to is refused (robo_comp.match.plausibility).
    fix: Any = None

    # RobotView for tasks -------------------------------------------------
    def cell(self) -> tuple[int, int]:
        """The robot's current cell."""
        cell: tuple[int, int] = self.driver.cell()
        return cell

    def in_bounds(self, x: int, y: int) -> bool:
        """True when (x, y) is a free cell of the arena."""
        return in_bounds(self.host.walls, x, y)

    def free_cell(self) -> tuple[int, int]:
        """The free cell the robot believes it is in (a noisy estimate may round into a wall)."""
        x, y, _ = self.driver.pose
        return free_cell(self.host.walls, x, y)

    def plan_to(self, goal: tuple[int, int]) -> list[tuple[int, int]] | None:
        """A 4-connected path from the (free) cell the robot believes it is in to ``goal``, around
        the cells where the other robots here are now; straight through them when there is no
        way around. (Tasks ``yield Plan(goal)`` instead: the host plans that off its loop.)"""
        return plan_around(self.host.walls, self.free_cell(), goal, self.others_cells())

    def others_cells(self) -> set[tuple[int, int]]:
        """The cells the other robots run here stand in now, and those of other hosts' robots the
        camera sees (:mod:`robo_comp.robots.oneworld`)."""
        me = self
        cells = {r.cell() for r in self.host.robots.values() if r is not me}
        world = self.host.world
        foreign = self.host.foreign
        if world is not None and foreign is not None:
            for rid in foreign.seen:
                if rid in world:
                    p = world.pose(rid)
                    cells.add((int(round(p.x)), int(round(p.y))))
        return cells


class RuntimeEnv(Protocol):
    """What :class:`TaskRuntime` needs of whoever drives it (see the module docstring)."""

    def spec(self, r: SimRobot, name: str) -> TaskSpec | None:
        """Task ``name`` as robot ``r`` runs it (its uploaded code first), or None."""

    def plan(self, r: SimRobot, step: Plan) -> Any:
        """The path for ``step`` (a list of cells, or None: no path), or :data:`PLANNING` when it
        is being found elsewhere: :meth:`TaskRuntime.planned` gets it later."""

    def capture(self, r: SimRobot, t: RunningTask, label: str) -> None:
        """Take a picture with ``r``'s camera as evidence; its id goes into ``t.pictures``."""

    def compute(self, r: SimRobot, step: Compute) -> bool:
        """Team code of ``r`` computes: True when it has been waited for already (go on now),
        False to let the driver wait ``step.seconds``."""

    def task_ended(self, r: SimRobot, task_id: int, ok: bool, status: str, result: Any) -> None:
        """Robot ``r``'s task ``task_id`` ended: tell the match."""

    def interrupted(self, r: SimRobot, t: RunningTask, by_task_id: int) -> None:
        """Robot ``r``'s task ``t`` is to be interrupted by task ``by_task_id`` (the plugins' hook)."""


class TaskRuntime:
    """Runs the tasks of the robots of one host or engine (see the module docstring)."""

    def __init__(self, env: RuntimeEnv) -> None:
        self.env = env
        #: Robots waiting for a path planned elsewhere, by robot id.
        self.planning: dict[str, SimRobot] = {}

    def start(self, r: SimRobot, task: dict[str, Any]) -> None:
        """Begin ``task`` (``task_id``, ``name``, ``args``) on ``r``, validated again here, as the
        robot must: a task it does not have, or arguments that do not fit, end it at once."""
        r.pending = None
        r.driver.bump = None  # a bump that ended the task before is not this task's
        spec = self.env.spec(r, task["name"])
        try:
            if spec is None:
                raise TaskFailed(f"this robot has no task {task['name']!r}")
            args = check_args(spec.advert(), task.get("args", []))
            r.task = RunningTask(task["task_id"], task["name"], spec.run(r, *args))
        except (TaskFailed, RoboCompError) as e:
            r.task = RunningTask(task["task_id"], task["name"], no_steps())
            self.done(r, False, str(e), reason="refused")
            return
        self.advance(r)

    def interrupt(self, r: SimRobot, task: dict[str, Any]) -> None:
        """A task given "now" while ``r`` runs another: it starts at once if ``r`` stands still,
        else at the end of the current movement."""
        if r.task is not None:
            self.env.interrupted(r, r.task, task["task_id"])
        if r.task is None or not r.driver.moving:
            if r.task is not None:
                self.done(r, False, f"interrupted by task {task['task_id']}", reason="interrupted")
            self.start(r, task)
        else:
            r.pending = task

    def boundary(self, r: SimRobot) -> None:
        """``r``'s driver finished a step (or a bump ended it): end a bumped task, switch to a
        pending one, or ask the task for its next step."""
        bump = r.driver.bump
        if bump is not None and r.task is not None:
            other = r.host.robots.get(bump.get("other") or "")
            self.done(r, False, stop_status(bump, f"robot {other.tag}" if other is not None else None),
                      reason="bumped")
        elif r.pending is not None:
            nxt = r.pending
            self.done(r, False, f"interrupted by task {nxt['task_id']}", reason="interrupted")
            self.start(r, nxt)
        elif r.task is not None:
            self.advance(r)

    def advance(self, r: SimRobot) -> None:
        """Ask the task for its next step (the robot is at a movement boundary)."""
        t = r.task
        assert t is not None
        while True:
            try:
                step = t.gen.send(t.answer)
                t.answer = None
            except StopIteration as stop:
                self.done(r, True, "done", stop.value)
                return
            except TaskFailed as e:
                self.done(r, False, str(e), reason=e.reason, line=e.line, traceback=e.traceback)
                return
            except Exception as e:  # a task bug must not take the host down
                self.done(r, False, f"task {t.name} crashed: {e!r}", reason="crashed")
                return
            if isinstance(step, Plan):  # the robot waits at its boundary meanwhile
                path = self.env.plan(r, step)
                if path is PLANNING:
                    self.planning[r.robot_id] = r
                    return
                t.answer = path
                continue
            if isinstance(step, Compute) and self.env.compute(r, step):
                if r.task is not t:  # the wait ended it (a bump, a stop, the end of the match)
                    return
                continue
            if isinstance(step, Capture):
                self.env.capture(r, t, step.label)
            r.driver.begin(step)
            return

    def planned(self, r: SimRobot, path: Answer, error: Exception | None = None) -> None:
        """The path robot ``r``'s task waited for (``error``: planning failed, which fails the task)."""
        self.planning.pop(r.robot_id, None)
        t = r.task
        if t is None:
            return
        t.plan = None
        if error is not None:  # a planner bug fails this task, not the host
            self.done(r, False, f"planning failed: {error!r}", reason="crashed")
            return
        t.answer = path
        self.advance(r)

    def take_plans(self) -> None:
        """Hand finished plans (futures) to their tasks (a task replaced or stopped meanwhile drops
        its plan)."""
        for rid, r in list(self.planning.items()):
            t = r.task
            if t is None or t.plan is None:
                del self.planning[rid]
            elif t.plan.done():
                try:
                    path = t.plan.result()
                except Exception as e:
                    self.planned(r, None, e)
                    continue
                self.planned(r, path)

    def done(self, r: SimRobot, ok: bool, status: str, result: Any = None, *, reason: str | None = None,
             line: int | None = None, traceback: list[str] | None = None) -> None:
        """End ``r``'s task: the robot halts, team code still running is cancelled, the match is told.
        A failed task's result says why in a word (``reason``: ``refused``, ``failed``, ``bumped``,
        ``interrupted``, ``crashed``, or what the sandbox said of team code: ``error``, ``limit``,
        ``cancelled``, ``restart``) and, for team code, the ``line`` that raised and the ``traceback``
        through the team's files."""
        t = r.task
        if t is None:
            return
        if reason is not None and (result is None or isinstance(result, dict)):
            result = dict(result or {}, reason=reason, **({"line": line} if line is not None else {}),
                          **({"traceback": traceback} if traceback else {}))
        if t.pictures and (result is None or isinstance(result, dict)):
            result = dict(result or {}, pictures=list(t.pictures))
        r.task = None
        t.gen.close()  # team code still running is cancelled here
        r.driver.halt()
        self.env.task_ended(r, t.id, ok, status, result)

    @staticmethod
    def halt(r: SimRobot) -> None:
        """Stop at once: no movement, no task, nothing pending (the match cancels them)."""
        r.driver.halt()
        if r.task is not None:
            r.task.gen.close()
        r.task = None
        r.pending = None


__all__ = ["PLANNING", "plan_around", "RobotWorld", "RunningTask", "RuntimeEnv", "SimRobot", "TaskRuntime"]

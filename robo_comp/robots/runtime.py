"""The task runtime: how a robot runs its tasks, the same on a robot host and on the engine.

A task is a generator of steps (:mod:`robo_comp.robots.steps`). :class:`TaskRuntime` runs one per
robot: it asks the generator for a step, hands movements to the robot's driver, plans paths
(:class:`~robo_comp.robots.steps.Plan`), takes pictures (:class:`~robo_comp.robots.steps.Capture`),
lets team code compute (:class:`~robo_comp.robots.steps.Compute`), switches to a task given "now"
at the next movement boundary (an *interrupt*), ends a task a bump stopped, and reports the end.

Before each :class:`~robo_comp.robots.steps.Move` it looks where the robot is going (teammates
never run into each other, and what the map does not show is reported): a cell a teammate stands
in or drives to is waited for (a :class:`~robo_comp.robots.steps.Wait` of :data:`HOLD_STEP`), and
after :data:`HOLD_REPLAN` the task gets a :class:`~robo_comp.robots.steps.Replan` and plans around
the teammates; of two robots waiting for each other one makes way (:mod:`robo_comp.robots.traffic`:
the one with the nearer refuge off the other's path drives there and waits until it has passed). A
robot of another host or team its sensors see driving into the cell goes first, as a teammate
would. A cell the robot's sensors see blocked that its team's map shows free is an obstacle: reported
(:meth:`RuntimeEnv.obstacle`: the team's map, so every teammate's planner routes around it) and
the task plans again. A move that did not end in its cell (a positioning fix moved the robot)
answers :class:`~robo_comp.robots.steps.Replan` too: the task plans again from where the robot is.

It does this through a :class:`RuntimeEnv`, which is what differs between its two drivers:

* a robot host (:class:`robo_comp.robots.host.RobotHost`) plans off its loop (:mod:`robo_comp.robots.planning`), uploads pictures to
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
from robo_comp.robots.steps import (
    Answer, Capture, CellPath, Compute, Move, Plan, Record, Replan, Step, TaskFailed, TaskRun, TaskSpec, Wait,
    no_steps,
)
from robo_comp.robots import traffic
from robo_comp.robots.teamcode import free_cell, in_bounds, stop_status
from robo_comp.world.planner import find_path
from robo_comp.world.video import FPS, MAX_FRAMES

log = logging.getLogger("robo_comp.robots")

#: What :meth:`RuntimeEnv.plan` returns while the path is being found elsewhere.
PLANNING = object()
#: Seconds a robot waits at a time for a teammate to clear the cell it is to drive into.
HOLD_STEP = 0.25
#: Seconds of waiting for one cell after which the task plans again, around its teammates.
HOLD_REPLAN = 1.0
#: Seconds a robot making way waits for the teammate to pass (then it goes on whatever).
WAY_LIMIT = 20.0
#: A task whose video is being uploaded looks again every UPLOAD_STEP seconds, for UPLOAD_WAIT at most.
UPLOAD_STEP = 0.05
UPLOAD_WAIT = 10.0
#: Where the robot believes it is, measured from a cell's centre (cells): within :data:`THERE` it
#: is in the cell already (a move there is skipped); a move ends off its path beyond
#: :data:`OFF_PATH` (a fix moved the robot: the task plans again), and the next move's cell must be
#: within :data:`NEXT` (a neighbour, diagonals included).
THERE = 0.3
OFF_PATH = 0.75
NEXT = 1.75


def _off(r: SimRobot, cell: tuple[int, int], limit: float) -> bool:
    """Whether robot ``r`` believes it is farther than ``limit`` cells from ``cell``'s centre."""
    x, y, _ = r.driver.pose
    return (x - cell[0]) ** 2 + (y - cell[1]) ** 2 > limit * limit


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
    #: A move waiting for a teammate to clear its cell, and how long it has waited.
    held: Move | None = None
    waited: float = 0.0
    #: The move in progress: the cell it left and the cell it drives to (what teammates keep off).
    leaving: tuple[int, int] | None = None
    to: tuple[int, int] | None = None
    #: The task's last planned path (where teammates must not wait for it: robots.traffic).
    path: CellPath | None = None
    #: Making way for a teammate (:mod:`robo_comp.robots.traffic`), when it does.
    way: GiveWay | None = None
    #: The video being filmed (a :class:`~robo_comp.robots.steps.Record` started it) and the ids of
    #: those uploaded.
    film: Film | None = None
    videos: list[int] = field(default_factory=list)
    #: Videos sent and not yet answered (a host's): the task waits for their ids before it goes on.
    uploads: int = 0
    upload_wait: float = 0.0


@dataclass(slots=True)
class Film:
    """A video being filmed: its label, its frames, seconds until the next frame."""

    label: str
    frames: list[Any] = field(default_factory=list)
    due: float = 0.0


@dataclass(slots=True)
class GiveWay:
    """A robot making way for a teammate: the cells still to drive to its refuge, the cells it left
    (the teammate is to pass them), the teammate's robot id, the seconds it has waited."""

    cells: list[tuple[int, int]]
    left: list[tuple[int, int]]
    other: str
    waited: float = 0.0


def plan_around(walls: Any, start: tuple[int, int], goal: tuple[int, int],
                occupied: set[tuple[int, int]]) -> list[tuple[int, int]] | None:
    """A path from ``start`` to ``goal`` around the ``occupied`` cells, straight through them when
    there is no way around (None: no path at all). Pure: a host runs it in its planner process or thread (:mod:`robo_comp.robots.planning`)."""
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
    """What a robot sees of the place that runs it (a robot host, or the engine's team side)."""

    walls: Any  # the map's wall grid [y, x]
    blocked: Any  # what the robot's planner avoids: the map's walls and its team's reported obstacles
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

    def pose(self) -> tuple[float, float, float]:
        """Where the robot believes it is: ``(x, y, heading)``."""
        x, y, h = self.driver.pose
        return x, y, h

    def claim(self) -> tuple[tuple[int, int], ...]:
        """The cells this robot holds (:func:`robo_comp.robots.traffic.claim`): a teammate enters none."""
        return traffic.claim(self)

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
        return plan_around(self.host.blocked, self.free_cell(), goal, self.others_cells())

    def others_cells(self) -> set[tuple[int, int]]:
        """The cells the other robots run here hold now (:meth:`claim`), and those of other
        hosts' robots the camera sees (:mod:`robo_comp.robots.oneworld`)."""
        me = self
        cells = {c for r in self.host.robots.values() if r is not me for c in r.claim()}
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

    def frame(self, r: SimRobot) -> Any:
        """A frame of ``r``'s camera now (an RGB array) for the video being filmed."""

    def video(self, r: SimRobot, t: RunningTask, frames: list[Any], label: str) -> None:
        """Make ``frames`` a video and upload it as ``r``'s evidence; its id goes into ``t.videos``."""

    def interrupted(self, r: SimRobot, t: RunningTask, by_task_id: int) -> None:
        """Robot ``r``'s task ``t`` is to be interrupted by task ``by_task_id`` (the plugins' hook)."""

    def obstacle(self, r: SimRobot, cell: tuple[int, int]) -> None:
        """Robot ``r``'s sensors saw ``cell`` blocked where its team's map shows it free: mark it on
        the robot's own map now (``r.host.blocked``) and report it for the team's map."""


class TaskRuntime:
    """Runs the tasks of the robots of one host or engine (see the module docstring)."""

    def __init__(self, env: RuntimeEnv) -> None:
        self.env = env
        #: Robots waiting for a path planned elsewhere, by robot id.
        self.planning: dict[str, SimRobot] = {}
        #: Robots filming, by robot id.
        self.filming: dict[str, SimRobot] = {}

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
        pending one, or ask the task for its next step (a move that did not end in its cell
        answers :class:`~robo_comp.robots.steps.Replan`)."""
        bump = r.driver.bump
        t = r.task
        if t is not None and t.to is not None:
            to, t.leaving, t.to = t.to, None, None
            if bump is None and t.way is None and _off(r, to, OFF_PATH):  # a fix moved it, or it fell short
                t.answer = Replan("off path", to)
        if bump is not None and t is not None:
            other = r.host.robots.get(bump.get("other") or "")
            self.done(r, False, stop_status(bump, f"robot {other.tag}" if other is not None else None),
                      reason="bumped")
        elif r.pending is not None:
            nxt = r.pending
            self.done(r, False, f"interrupted by task {nxt['task_id']}", reason="interrupted")
            self.start(r, nxt)
        elif t is not None:
            self.advance(r)

    def advance(self, r: SimRobot) -> None:
        """Ask the task for its next step (the robot is at a movement boundary); a move waiting for
        a teammate is looked at again first."""
        t = r.task
        assert t is not None
        while True:
            step: Step
            if t.uploads > 0 and t.upload_wait < UPLOAD_WAIT:  # its video's id is to be in the result
                t.upload_wait += UPLOAD_STEP
                r.driver.begin(Wait(UPLOAD_STEP))
                return
            if t.way is not None:
                if self._give_way(r, t, t.way):
                    return
                continue  # the teammate passed: the task plans again (t.answer)
            if t.held is not None:
                step, t.held = t.held, None
            else:
                try:
                    step = t.gen.send(t.answer)
                    t.answer = None
                except StopIteration as stop:
                    self.done(r, True, "done", stop.value)
                    return
                except TaskFailed as e:
                    self.done(r, False, str(e), e.details or None, reason=e.reason, line=e.line,
                              traceback=e.traceback)
                    return
                except Exception as e:  # a task bug must not take the host down
                    self.done(r, False, f"task {t.name} crashed: {e!r}", reason="crashed")
                    return
            if isinstance(step, Plan):  # the robot waits at its boundary meanwhile
                path = self.env.plan(r, step)
                if path is PLANNING:
                    self.planning[r.robot_id] = r
                    return
                t.answer = t.path = path
                continue
            if isinstance(step, Compute) and self.env.compute(r, step):
                if r.task is not t:  # the wait ended it (a bump, a stop, the end of the match)
                    return
                continue
            if isinstance(step, Move):
                if self._move(r, t, step):
                    return
                continue  # not driven: the task hears why (t.answer) and goes on
            if isinstance(step, Record):
                self._record(r, t, step.label)
                continue
            if isinstance(step, Capture):
                self.env.capture(r, t, step.label)
            r.driver.begin(step)
            return

    def _move(self, r: SimRobot, t: RunningTask, step: Move) -> bool:
        """Drive ``step`` if the way is clear; else wait for a teammate, step aside, or answer the
        task with a :class:`~robo_comp.robots.steps.Replan` (False: nothing was begun)."""
        cell = (step.x, step.y)
        if not _off(r, cell, THERE):  # a fix put the robot there already
            return False
        if _off(r, cell, NEXT):
            t.answer = Replan("off path", cell)
            return False
        blocked = r.host.blocked
        h, w = blocked.shape
        if not (0 <= cell[0] < w and 0 <= cell[1] < h) or blocked[cell[1], cell[0]]:
            t.answer = Replan("wall", cell)
            return False
        sees = getattr(r.driver, "sees_blocked", None)
        if sees is not None and sees(*cell):
            self.env.obstacle(r, cell)
            t.answer = Replan("obstacle", cell)
            return False
        other = traffic.holder(r, cell) or traffic.crossing(r, cell)
        crossed = getattr(r.driver, "sees_crossing", None)
        if other is None and not (crossed is not None and crossed(*cell)):
            t.waited = 0.0
            self._drive(r, t, cell, step)
            return True
        t.held = step  # waiting for the cell (as the teammate sees it, deciding who makes way)
        ot = other.task if other is not None else None
        if other is not None and ot is not None and ot.held is not None and (ot.held.x, ot.held.y) in r.claim():
            cells = traffic.make_way(r, other)
            if cells is not None:  # two robots waiting for each other: this one makes way
                t.held, t.waited = None, 0.0
                t.way = GiveWay(cells, [r.cell()], other.robot_id)
                return self._give_way(r, t, t.way)
        if t.waited >= HOLD_REPLAN:  # a teammate (or another team's robot driving in) keeps the cell
            t.held, t.waited = None, 0.0
            t.answer = Replan("teammate" if other is not None else "robot", cell)
            return False
        t.waited += HOLD_STEP
        r.driver.begin(Wait(HOLD_STEP))
        return True

    def _give_way(self, r: SimRobot, t: RunningTask, way: GiveWay) -> bool:
        """Drive on to the refuge, or wait there until the teammate has passed (True: a step began);
        False once the way is made: the task gets a :class:`~robo_comp.robots.steps.Replan`."""
        other = r.host.robots.get(way.other)
        if way.waited >= WAY_LIMIT or (not way.cells and traffic.passed(other, way.left)):
            t.way = None
            t.answer = Replan("teammate", way.left[0])
            return False
        if way.cells:
            nxt = way.cells[0]
            sees = getattr(r.driver, "sees_blocked", None)
            if sees is not None and sees(*nxt):
                self.env.obstacle(r, nxt)
                t.way = None
                t.answer = Replan("obstacle", nxt)
                return False
            if traffic.holder(r, nxt) is None:
                way.cells.pop(0)
                way.left.append(r.cell())
                self._drive(r, t, nxt, Move(*nxt))
                return True
        way.waited += HOLD_STEP
        r.driver.begin(Wait(HOLD_STEP))
        return True

    def _record(self, r: SimRobot, t: RunningTask, label: str | None) -> None:
        """Start filming (a frame now), or stop and hand the video to the env to upload."""
        if label is not None:
            t.film = Film(label[:64], [self.env.frame(r)], 1.0 / FPS)
            self.filming[r.robot_id] = r
            return
        self.filming.pop(r.robot_id, None)
        film, t.film = t.film, None
        if film is not None and film.frames:
            self.env.video(r, t, film.frames, film.label)

    def film(self, dt: float) -> None:
        """``dt`` seconds passed: a frame for each video being filmed when one is due."""
        for rid, r in list(self.filming.items()):
            t = r.task
            film = t.film if t is not None else None
            if film is None:
                del self.filming[rid]
                continue
            film.due -= dt
            if film.due <= 0 and len(film.frames) < MAX_FRAMES:
                film.due += 1.0 / FPS
                film.frames.append(self.env.frame(r))

    @staticmethod
    def _drive(r: SimRobot, t: RunningTask, cell: tuple[int, int], step: Move) -> None:
        t.leaving, t.to = r.cell(), cell
        r.driver.begin(step)

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
        t.path = path if isinstance(path, list) else None
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
        if t.videos and (result is None or isinstance(result, dict)):
            result = dict(result or {}, videos=list(t.videos))
        self.filming.pop(r.robot_id, None)  # a film not stopped by its task is not uploaded
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


__all__ = ["Film", "GiveWay", "HOLD_REPLAN", "HOLD_STEP", "PLANNING", "plan_around", "RobotWorld", "RunningTask", "RuntimeEnv", "SimRobot", "TaskRuntime"]

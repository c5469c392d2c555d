"""Uploaded team code on a robot host: the bridge between the host's loop and its sandbox.

One :class:`TeamCode` per robot host holds one :class:`~robo_comp.sandbox.parent.Sandbox`
(a limited child process, see ``docs/sandbox.md``). The host's single poll loop drives it:
:meth:`TeamCode.fileno` joins the host's poller and :meth:`TeamCode.pump` handles what the
sandbox says. Nothing here starts a thread.

* **Uploads** arrive from the core as ``upload`` requests; the module is checked and loaded in
  the sandbox (the checked init contract) and the answer goes back to the core with, per robot,
  ``ok`` or the checked error (file, line, rule). A failed upload leaves the robot with what it
  had: the sandbox switches modules in only on success.
* **Tasks** of uploaded modules run as ordinary task generators (:meth:`TeamCode.task_spec`):
  team code's movement calls (``move``, ``turn``, ``go_to``) become the host's movement steps,
  so an interrupt still takes effect at a movement boundary and a stop halts at once (the run is
  cancelled when its generator is closed). Between movements the generator waits a tick.
* A robot runs only the modules uploaded *to it*; the host's robots share the sandbox process,
  so a module's newest version applies to every robot of the host that has it.
* **Step-locked** (``step_locked=True``, the engine's mode): every call waits for its run's turn;
  a run computes while its task yields :class:`~robo_comp.robots.steps.Compute`, and the engine
  waits for it (:meth:`TeamCode.wait_run`) with its clock stopped, so the runs of a team's robots
  take turns in the same order every time, and the calls that take no time are answered in that
  order, each paid from the robot's call budget (``pacer``) in simulated time.
"""
from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Generator
from dataclasses import dataclass, field
from typing import Any, Protocol

from robo_comp.errors import RoboCompError, UploadError
from robo_comp.protocol import drawing
from robo_comp.sandbox.api import MOVEMENTS
from robo_comp.sandbox.contract import source_hash
from robo_comp.sandbox.parent import (
    PENDING, Drawing, Limits, LoadFailed, Loaded, LogLine, RpcCall, Sandbox, SandboxRestarted, SandboxStopped,
    TaskDone, TaskFailed as SbFailed,
)
from robo_comp.robots.steps import Compute, Move, Plan, Replan, Step, TaskFailed, TaskSpec, Turn, Wait
from robo_comp.world.planner import find_path

log = logging.getLogger("robo_comp.robots.teamcode")

Reply = Callable[[bool, dict[str, Any]], None]


class CodeRobot(Protocol):
    """What team code sees of one hosted robot (a :class:`robo_comp.robots.runtime.SimRobot`)."""

    robot_id: str
    tag: int
    driver: Any  # the robot's driver: ``pose``, ``heading`` and ``bump``

    def cell(self) -> tuple[int, int]: ...  # noqa: D102
    def free_cell(self) -> tuple[int, int]: ...  # noqa: D102
    def in_bounds(self, x: int, y: int) -> bool: ...  # noqa: D102


class CodeHost(Protocol):
    """What :class:`TeamCode` needs of its robot host (a :class:`robo_comp.robots.host.RobotHost`):
    the host's robots and world, and the requests team code makes through the host's connection."""

    team: str | None
    seed: int
    pm: Any  # the host's plugin manager (extension hooks are called through it)
    by_tag: dict[int, Any]  # tag -> CodeRobot
    world: Any  # the host's simulated arena (``sense``), None until it knows the arena
    walls: Any  # the map's wall grid ``[y, x]``
    blocked: Any  # the walls as the team knows them: the map's and the obstacles its robots reported

    def upload_answered(self, rid: int, results: list[dict[str, Any]]) -> None:
        """Answer the core's ``upload`` request ``rid`` with one result per robot."""

    def team_log(self, tag: int | None, stream: str, text: str) -> None:
        """Forward a line the team's code printed (or the sandbox said) to the team's console."""

    def code_request(self, type_: str, body: dict[str, Any], on_reply: Reply) -> None:
        """Send a request to the core on team code's behalf; ``on_reply(ok, body)`` gets the answer."""

    def code_picture(self, r: Any, on_reply: Reply) -> None:
        """Take a picture with robot ``r`` and send it to the core; ``on_reply(ok, body)`` gets its id."""

    def team_draw(self, tags: list[int], frames: list[list[Any]]) -> None:
        """Send the robots' new frames of debug drawing to the core (a ``draw`` notification)."""

#: How long a team-code task waits between two looks at its sandbox (one host tick at most).
WAIT_SECONDS = 0.02
#: The largest piece of map team code may ask for (cells from the robot).
MAX_PIECE_RADIUS = 20
#: The most picture ids one reported find passes on as evidence (what the core accepts).
MAX_EVIDENCE = 32


class Refused(Exception):
    """A robot call that cannot be carried out; its message reaches team code as RobotError."""


# The answers to team code's robot calls, as plain functions of the walls and the robot's belief,
# so that the seeded bench of robo_comp.testing answers exactly as a robot host does.
def in_bounds(walls: Any, x: int, y: int) -> bool:
    """True when (x, y) is a free cell of ``walls`` (a bool grid ``walls[y, x]``)."""
    return 0 <= y < walls.shape[0] and 0 <= x < walls.shape[1] and not walls[y, x]


def free_cell(walls: Any, x: float, y: float) -> tuple[int, int]:
    """The free cell a robot at (x, y) believes it is in (a noisy estimate may round into a wall)."""
    cell = (int(round(x)), int(round(y)))
    if in_bounds(walls, *cell):
        return cell
    near = [(int(math.floor(x)) + dx, int(math.floor(y)) + dy) for dx in (0, 1) for dy in (0, 1)]
    free = [c for c in near if in_bounds(walls, *c)]
    return min(free, key=lambda c: (c[0] - x) ** 2 + (c[1] - y) ** 2) if free else cell


def move_direction(heading: float) -> tuple[int, int]:
    """The cell step of ``robot.move`` for a heading in degrees (between two axes: the nearer one)."""
    rad = math.radians(heading)
    dx, dy = round(math.cos(rad)), round(math.sin(rad))
    if dx and dy:
        dx, dy = (dx, 0) if abs(math.cos(rad)) >= abs(math.sin(rad)) else (0, dy)
    return dx, dy


def plan_path(walls: Any, start: tuple[int, int], goal: tuple[int, int]) -> list[tuple[int, int]]:
    """``robot.plan``/``robot.go_to``: a path from ``start`` to a free ``goal``, or :class:`Refused`."""
    if not in_bounds(walls, *goal):
        raise Refused(f"({goal[0]}, {goal[1]}) is a wall or outside the arena")
    path = find_path(walls, start, goal)
    if path is None:
        raise Refused(f"no path to ({goal[0]}, {goal[1]})")
    return path


def call_failed(name: str, args: Any, error: Exception) -> str:
    """What team code is told when answering ``robot.NAME(*args)`` failed on the host's side."""
    shown = ", ".join(repr(a) for a in args)
    return f"robot.{name}({shown:.80}) failed: {error}"


def stop_status(bump: dict[str, Any], other: str | None) -> str:
    """Why a movement stopped, for the task's status: a bump (into ``other``, a robot, or what
    the arena names), or the driver's own failure (``error``, e.g. a lost link to a real robot)."""
    if bump.get("error"):
        return f"stopped at ({bump['x']:.1f}, {bump['y']:.1f}): {bump['error']}"
    what = other or bump.get("what", "something")
    return f"bumped into {what} at ({bump['x']:.1f}, {bump['y']:.1f}) and stopped"


def map_piece(walls: Any, x: int, y: int, radius: int) -> dict[str, Any]:
    """``robot.map_piece``: the walls within ``radius`` cells of (x, y), outside the map blocked."""
    if not 0 <= radius <= MAX_PIECE_RADIUS:
        raise Refused(f"radius must be between 0 and {MAX_PIECE_RADIUS}")
    h, w = walls.shape
    rows = [[1 if not (0 <= yy < h and 0 <= xx < w) or walls[yy, xx] else 0
             for xx in range(x - radius, x + radius + 1)] for yy in range(y - radius, y + radius + 1)]
    return {"x0": x - radius, "y0": y - radius, "walls": rows}


class CallSite(Protocol):
    """Where one robot's calls are answered: a robot of a robot host, or of the bench.

    The robot call table (:data:`ROBOT_CALLS`, :func:`movement_steps`) answers team code through
    this interface only, so a host and the seeded bench give the same answers."""

    @property
    def walls(self) -> Any:
        """The walls as the robot's team knows them, ``[y, x]``: the map's and the obstacles its
        robots reported (read only: a host's robot reads its host's)."""

    def pose(self) -> tuple[float, float, float]:
        """The robot's believed ``(x, y, heading)``."""

    def cell(self) -> tuple[int, int]:
        """The cell the robot believes it is in."""

    def free_cell(self) -> tuple[int, int]:
        """The free cell the robot believes it is in (see :func:`free_cell`)."""

    def sense(self) -> dict[str, Any]:
        """The range-sensor readings."""

    def picture(self, on_reply: Reply) -> None:
        """Take a camera picture; ``on_reply(ok, body)`` gets ``{"id", "seen"}`` (or an error)."""

    def request(self, type_: str, body: dict[str, Any], on_reply: Reply) -> None:
        """A request to the match (``find``, ``radio``) on this robot's behalf."""

    def draw(self, shapes: Any) -> None:
        """The robot's new frame of debug drawing as the sandbox sent it (checked where it is
        recorded, :class:`DebugCanvas`), for its team's views."""


Settle = Callable[[bool, Any], None]


def _position(s: CallSite, args: list[Any], settle: Settle) -> Any:
    return [round(v, 3) for v in s.pose()]


def _sense(s: CallSite, args: list[Any], settle: Settle) -> Any:
    return s.sense()


def _plan(s: CallSite, args: list[Any], settle: Settle) -> Any:
    return [list(p) for p in plan_path(s.walls, s.free_cell(), (int(args[0]), int(args[1])))]


def _map_piece(s: CallSite, args: list[Any], settle: Settle) -> Any:
    return map_piece(s.walls, *s.cell(), int(args[0]))


def _take_picture(s: CallSite, args: list[Any], settle: Settle) -> Any:
    s.picture(lambda ok, body: settle(ok, body.get("id") if ok else body))
    return PENDING


def _look(s: CallSite, args: list[Any], settle: Settle) -> Any:
    s.picture(lambda ok, body: settle(ok, {"picture": body.get("id"), "victims": list(body.get("seen") or [])}
                                      if ok else body))
    return PENDING


def _report_find(s: CallSite, args: list[Any], settle: Settle) -> Any:
    x, y, kind, evidence = (list(args) + [None, None, None, None])[:4]
    body = {"x": float(x), "y": float(y), "kind": str(kind or "victim")[:32],
            "evidence": [int(e) for e in (evidence or [])][:MAX_EVIDENCE]}
    s.request("find", body, settle)
    return PENDING


def _report_obstacle(s: CallSite, args: list[Any], settle: Settle) -> Any:
    x, y = (list(args) + [None, None])[:2]
    if type(x) is not int or type(y) is not int:
        raise Refused("report_obstacle(x, y) takes a cell: two whole numbers")
    s.request("obstacle", {"x": x, "y": y}, lambda ok, b: settle(ok, b.get("new") if ok else b))
    return PENDING


def _radio(s: CallSite, args: list[Any], settle: Settle) -> Any:
    to, data = (list(args) + [None, None])[:2]
    s.request("radio", {"to": to, "data": data}, lambda ok, b: settle(ok, b.get("delivered") if ok else b))
    return PENDING


def _draw(s: CallSite, args: list[Any], settle: Settle) -> Any:
    s.draw(args[0] if args else None)  # checked when it is recorded (DebugCanvas.changed)
    return None


#: The robot calls that take no simulated time: name -> answer(site, args, settle). An answer
#: returns the value, or PENDING and later calls ``settle(ok, value or error body)``.
#: ``draw`` is the frame of debug drawing the sandbox sends with a movement call
#: (``robot.draw_dot``/``draw_line``/``draw_text`` collect it in the sandbox, see
#: :mod:`robo_comp.protocol.drawing`): no answer goes back, and no call budget is drawn.
ROBOT_CALLS: dict[str, Callable[[CallSite, list[Any], Settle], Any]] = {
    "position": _position, "sense": _sense, "plan": _plan, "map_piece": _map_piece,
    "take_picture": _take_picture, "upload_picture": _take_picture, "look": _look,
    "report_find": _report_find, "radio": _radio, "report_obstacle": _report_obstacle, "draw": _draw,
}
#: The robot API team code sees in the sandbox that is answered in the sandbox itself (debug
#: drawing: collected there, sent as one ``draw`` with the next movement call).
DRAW_CALLS = ("draw_dot", "draw_line", "draw_text")


def no_settle(ok: bool, value: Any) -> None:
    """The ``settle`` of a call that gets no answer (``draw``)."""


def take_drawing(site: CallSite, rec: Drawing) -> None:
    """A :class:`~robo_comp.sandbox.parent.Drawing` from the sandbox, through the call table."""
    answer_call(site, "draw", [rec.shapes], no_settle)


@dataclass(slots=True)
class DebugCanvas:
    """Every robot's newest frame of debug drawing, and which of them to record next tick.

    The same on a robot host (sent to the core) and on the bench (written to the match log): a
    frame replaces the robot's last one; :meth:`changed` gives, per team, the frames that differ
    from what was recorded last, at most once per :data:`~robo_comp.protocol.drawing.TICK`. A
    frame is checked (:func:`~robo_comp.protocol.drawing.clean_frame`) only then: a robot draws a
    frame before every movement, most are replaced before the next tick, and checking each cost
    the engine about 70 µs a 16-shape frame."""

    team_of: Callable[[int], str | None]
    frames: dict[int, list[list[Any]]] = field(default_factory=dict)
    recorded: dict[int, list[list[Any]]] = field(default_factory=dict)
    #: The newest frame of each robot as its sandbox sent it, not checked yet (one a robot).
    unchecked: dict[int, Any] = field(default_factory=dict)
    dirty: bool = False

    def draw(self, tag: int, shapes: Any) -> None:
        """Robot ``tag``'s new frame, as the sandbox sent it (untrusted: checked when recorded)."""
        self.unchecked[tag] = shapes
        self.dirty = True

    def changed(self) -> dict[str, tuple[list[int], list[list[list[Any]]]]]:
        """Per team, ``(tags, frames)`` of the frames not yet recorded (in tag order), checked;
        marks them recorded."""
        out: dict[str, tuple[list[int], list[list[list[Any]]]]] = {}
        if not self.dirty:
            return out
        self.dirty = False
        for tag, raw in self.unchecked.items():
            self.frames[tag] = drawing.clean_frame(raw)
        self.unchecked.clear()
        for tag in sorted(self.frames):
            shapes = self.frames[tag]
            if self.recorded.get(tag, []) == shapes:
                continue
            self.recorded[tag] = shapes
            team = self.team_of(tag)
            if team is not None:
                tags, frames = out.setdefault(team, ([], []))
                tags.append(tag)
                frames.append(shapes)
        return out

    def record(self, events: list[dict[str, Any]], t: float) -> None:
        """Append one ``debug.draw`` event per team with new frames to a bench's event list
        (the match's limits do not count them: drawing costs nothing)."""
        for team, (tags, frames) in self.changed().items():
            events.append({"t": t, "topic": "debug.draw", "team": team, "tags": tags, "frames": frames})
#: The robot calls that move the robot: they become movement steps (:func:`movement_steps`).
MOVEMENT_CALLS = MOVEMENTS


def answer_call(site: CallSite, name: str, args: list[Any], settle: Settle) -> Any:
    """Answer robot call ``name(*args)`` that takes no time, from the table; :class:`Refused`
    for an unknown call or one that cannot be carried out."""
    answer = ROBOT_CALLS.get(name)
    if answer is None:
        raise Refused(f"unknown robot call {name!r}")
    return answer(site, list(args), settle)


def movement_steps(site: CallSite, name: str, args: list[Any]) -> Generator[Step, Any, Any]:
    """The movement steps of ``move``, ``turn`` or ``go_to``: what the host's driver carries
    out and the bench's arena simulates. ``go_to`` yields a :class:`Plan` and expects the path
    (None: no path) sent back, and plans again (around the teammates in the way) whenever the
    runtime answers a move with a :class:`~robo_comp.robots.steps.Replan`. Raises
    :class:`Refused` when the way is blocked."""
    if name == "turn":
        yield Turn(float(args[0]))
        return
    walls = site.walls
    if name == "move":
        cells = int(args[0])
        dx, dy = move_direction(site.pose()[2])
        sign = 1 if cells >= 0 else -1
        for _ in range(abs(cells)):
            x, y = site.cell()
            nx, ny = x + sign * dx, y + sign * dy
            if not in_bounds(walls, nx, ny):
                raise Refused(f"({nx}, {ny}) is a wall or outside the arena; stopped at ({x}, {y})")
            answer = yield Move(nx, ny)
            if isinstance(answer, Replan):
                raise Refused(f"{_REPLANS.get(answer.reason, answer.reason)} ({nx}, {ny}); stopped at {site.cell()}")
        return
    goal = (int(args[0]), int(args[1]))
    if not in_bounds(walls, *goal):
        raise Refused(f"({goal[0]}, {goal[1]}) is a wall or outside the arena")
    avoid = False  # the first plan around walls only; a re-plan around the teammates in the way too
    stuck = plans = 0
    while stuck < GO_TO_PLANS and plans < 10 * GO_TO_PLANS:
        if site.cell() == goal:
            return
        stuck += 1
        plans += 1
        path = yield Plan(goal, avoid_robots=avoid)  # the host plans off its loop; the bench at once
        if not isinstance(path, list):
            raise Refused(f"no path to ({goal[0]}, {goal[1]})")
        for x, y in path[1:]:
            answer = yield Move(x, y)
            if isinstance(answer, Replan):
                avoid = True
                break
            stuck = 0
    if site.cell() != goal:
        raise Refused(f"did not reach ({goal[0]}, {goal[1]}) after {plans} plans; stopped at {site.cell()}")


#: Plans in a row a team code ``go_to`` makes without driving a cell before it gives up (a plan
#: follows every move the runtime answered with a :class:`~robo_comp.robots.steps.Replan`).
GO_TO_PLANS = 30
#: What team code is told when a ``move`` could not be made.
_REPLANS = {"teammate": "a teammate holds", "robot": "another robot is driving into", "obstacle": "an obstacle (reported for the team's map) blocks",
            "wall": "the team's map shows a wall at", "off path": "the robot is not next to"}


@dataclass(slots=True)
class HostSite:
    """A hosted robot as a :class:`CallSite`: its driver's belief, the host's world and link."""

    host: CodeHost
    r: CodeRobot
    canvas: DebugCanvas | None = None

    @property
    def walls(self) -> Any:  # noqa: D102
        return self.host.blocked

    def pose(self) -> tuple[float, float, float]:  # noqa: D102
        x, y, h = self.r.driver.pose
        return x, y, h

    def cell(self) -> tuple[int, int]:  # noqa: D102
        return self.r.cell()

    def free_cell(self) -> tuple[int, int]:  # noqa: D102
        return self.r.free_cell()

    def sense(self) -> dict[str, Any]:  # noqa: D102
        world = self.host.world
        return world.sense(self.r.robot_id) if world is not None else {}

    def picture(self, on_reply: Reply) -> None:  # noqa: D102
        self.host.code_picture(self.r, on_reply)

    def request(self, type_: str, body: dict[str, Any], on_reply: Reply) -> None:  # noqa: D102
        self.host.code_request(type_, dict(body, tag=self.r.tag), on_reply)

    def draw(self, shapes: Any) -> None:  # noqa: D102
        if self.canvas is not None:
            self.canvas.draw(self.r.tag, shapes)


@dataclass(slots=True)
class CodeRun:
    """A task of team code running on one robot: the call it waits for an answer to (a movement,
    or in step-locked mode any call), and how it ended."""

    run_id: int
    tag: int
    task: str
    call: RpcCall | None = None
    outcome: TaskDone | SbFailed | None = None


@dataclass(slots=True)
class LoadJob:
    """An upload being checked: who asked (the core's request id) and for which robots."""

    rid: int
    tags: list[int]
    filename: str
    sha256: str


@dataclass(slots=True)
class TeamCode:
    """The host's uploaded modules, their sandbox, and the runs of their tasks."""

    host: CodeHost
    limits: Limits = field(default_factory=Limits)
    #: The engine's mode (see the module docstring): calls answered in turn, runs waited for.
    step_locked: bool = False
    #: Step-locked: ``pacer(tag, call)`` -> simulated seconds the call waits for its robot's budget.
    pacer: Callable[[int, str], float] | None = None
    #: ``on_answer(tag, call, args, ok, value)``: every call answered (the engine logs them).
    on_answer: Callable[[int, str, list[Any], bool, Any], None] | None = None
    #: A replayable sandbox (hash seed from the host's seed, no address randomisation).
    deterministic: bool = False
    sb: Sandbox | None = None
    #: module names each robot may run (uploaded to that robot)
    enabled: dict[int, set[str]] = field(default_factory=dict)
    loads: dict[int, LoadJob] = field(default_factory=dict)
    runs: dict[int, CodeRun] = field(default_factory=dict)
    #: The robots' debug drawing, sent to the core at most once per drawing.TICK (real seconds here).
    canvas: DebugCanvas = field(init=False)
    next_draw: float = 0.0

    def __post_init__(self) -> None:
        self.canvas = DebugCanvas(lambda tag: self.host.team)

    # ------------------------------------------------------------------ the sandbox
    def _sandbox(self) -> Sandbox:
        if self.sb is None:  # started on the first upload, for the robots registered by then
            self.sb = Sandbox(self.host.team or "team", list(self.host.by_tag), None, self.limits,
                              seed=self.host.seed, deterministic=self.deterministic)
        return self.sb

    def add_tag(self, tag: int) -> None:
        """A robot registered (again) with ``tag``: its team code may act for it."""
        if self.sb is not None:
            self.sb.add_tag(tag)

    def fileno(self) -> int | None:
        """The sandbox's descriptor for the host's poller (None while there is no sandbox)."""
        if self.sb is None or not self.sb.alive:
            return None
        return self.sb.fileno()

    def wants_write(self) -> bool:
        """True when the sandbox has output waiting for its socket."""
        return self.sb is not None and self.sb.alive and self.sb.wants_write()

    def deadline(self) -> float | None:
        """When :meth:`pump` must run at the latest (a sandbox timer, or drawing to send)."""
        due = self.sb.deadline() if self.sb is not None else None
        if self.canvas.dirty and not self.step_locked:
            due = self.next_draw if due is None else min(due, self.next_draw)
        return due

    def close(self) -> None:
        """End the sandbox process."""
        if self.sb is not None:
            self.sb.close()
            self.sb = None

    # ------------------------------------------------------------------ uploads
    def upload(self, rid: int, tags: list[int], filename: str, source: str | bytes) -> None:
        """Check and load ``source`` for ``tags``; the answer goes to the core's request ``rid``."""
        sha = source_hash(source if isinstance(source, str) else bytes(source).decode("utf-8", "replace"))
        tags = [t for t in tags if t in self.host.by_tag]
        try:
            load_id = self._sandbox().begin_load(filename, source)
        except RoboCompError as e:
            self._answer_load(LoadJob(rid, tags, filename, sha), None, e)
            return
        self.loads[load_id] = LoadJob(rid, tags, filename, sha)

    def load_now(self, filename: str, source: str, tags: list[int], timeout: float = 10.0) -> Any:
        """Check and load ``source`` for ``tags`` at once (the engine's upload: it waits); returns
        the module's :class:`~robo_comp.sandbox.contract.ModuleInfo` or raises the checked
        :class:`~robo_comp.errors.UploadError`. Calls ``init(robot)`` makes are refused, as on a host."""
        sb = self._sandbox()
        lid = sb.begin_load(filename, source)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for rec in sb.poll(0.05):
                if isinstance(rec, Loaded) and rec.load_id == lid:
                    for t in tags:
                        self.enabled.setdefault(t, set()).add(rec.module.name)
                    return rec.module
                if isinstance(rec, LoadFailed) and rec.load_id == lid:
                    raise rec.error
                self._take(rec)
        raise UploadError(f"{filename}: timeout: no answer from the sandbox", file=filename, rule="timeout")

    def unload(self, tags: list[int], name: str) -> list[int]:
        """Take module ``name`` away from ``tags``; the sandbox drops it when no robot has it."""
        done = [t for t in tags if name in self.enabled.get(t, set())]
        for t in done:
            self.enabled[t].discard(name)
        if done and self.sb is not None and not any(name in s for s in self.enabled.values()):
            self.sb.unload(name)
        for t in done:
            self._notify("robo_comp_extension_unloaded", tag=t, name=name)
        return done

    def _notify(self, hook: str, **kwargs: Any) -> None:
        """Call a host-side extension hook; a plugin that raises is logged, never fatal to the host."""
        try:
            getattr(self.host.pm.hook, hook)(**kwargs)
        except Exception:
            log.exception("plugin hook %s failed", hook)

    def reset(self, tags: list[int]) -> list[dict[str, Any]]:
        """The referee's restart of this host's sandbox (one per team and host): ends a cool-down."""
        was = self.sb.reset() if self.sb is not None else False
        message = ("the sandbox was resting and restarts now with the team's modules" if was else
                   "the sandbox was running; its count of limit kills starts again from zero")
        return [{"tag": t, "ok": True, "restarted": was, "message": message} for t in tags]

    def modules(self, tag: int) -> list[dict[str, Any]]:
        """The modules robot ``tag`` has: name, version, kind, file, sha256, tasks."""
        if self.sb is None:
            return []
        mine = self.enabled.get(tag, set())
        return [m.plain() for m in self.sb.modules() if m.name in mine]

    def _answer_load(self, job: LoadJob, module: Any, err: RoboCompError | None) -> None:
        results: list[dict[str, Any]] = []
        replaced: list[int] = []
        for tag in job.tags:
            if err is None:
                mine = self.enabled.setdefault(tag, set())
                if module.name in mine:
                    replaced.append(tag)
                mine.add(module.name)
                results.append(dict(module.plain(), tag=tag, ok=True,
                                    message=f"{job.filename}: {module.name} {module.version} loaded"))
            else:
                details = getattr(err, "details", None) or {}
                results.append({"tag": tag, "ok": False, "message": str(err), "file": job.filename,
                                "rule": details.get("rule"), "line": details.get("line"),
                                "sha256": job.sha256})
        self.host.upload_answered(job.rid, results)
        if err is None:
            for tag in replaced:
                self._notify("robo_comp_extension_unloaded", tag=tag, name=module.name)
            for tag in job.tags:
                self._notify("robo_comp_extension_loaded", tag=tag, name=module.name, version=module.version,
                             sha256=module.sha256, tasks=sorted(module.tasks))

    # ------------------------------------------------------------------ tasks
    def adverts(self, tag: int) -> dict[str, dict[str, Any]]:
        """The task descriptions robot ``tag`` gains from its uploaded modules."""
        if self.sb is None:
            return {}
        mine = self.enabled.get(tag, set())
        out = {}
        for name, spec in self.sb.advertised_tasks().items():
            if spec.get("module") in mine:
                out[name] = {"name": name, "description": spec.get("description", ""),
                             "args": spec.get("args", [])}
        return out

    def task_spec(self, tag: int, name: str) -> TaskSpec | None:
        """A runnable spec for task ``name`` of robot ``tag`` from its uploaded code, or None."""
        advert = self.adverts(tag).get(name)
        if advert is None:
            return None
        return TaskSpec(name, lambda robot, *args: self._run(robot, name, list(args)), advert["args"],
                        advert["description"], source="upload")

    def _run(self, r: CodeRobot, name: str, args: list[Any]) -> Generator[Step, Any, Any]:
        """The task generator of a team-code task: movement steps from the sandbox's calls (and,
        step-locked, every other call answered in turn)."""
        sb = self._sandbox()
        try:
            run_id = sb.start_task(r.tag, name, args)
        except RoboCompError as e:
            raise TaskFailed(e.message, "refused") from None
        run = self.runs[run_id] = CodeRun(run_id, r.tag, name)
        try:
            while run.outcome is None:
                c = run.call
                if c is None:
                    yield Compute(WAIT_SECONDS, run_id)
                    continue
                run.call = None
                site = HostSite(self.host, r)
                if c.name not in MOVEMENT_CALLS:  # step-locked: answered now, in its turn
                    wait = self.pacer(r.tag, c.name) if self.pacer is not None else 0.0
                    if wait > 0:
                        yield Wait(wait)  # the robot's call budget: paid in simulated time
                    self._answer(c, *self._answer_now(site, c))
                    continue
                try:
                    steps = movement_steps(site, c.name, list(c.args))
                    sent = None
                    while True:  # forwards what the runtime answers (a planned path) into the steps
                        try:
                            step = steps.send(sent)
                        except StopIteration:
                            break
                        sent = yield step
                        if r.driver.bump is not None:
                            raise Refused("bumped into something and stopped")
                except Refused as e:
                    self._answer(c, False, str(e))
                except (TypeError, ValueError, IndexError) as e:
                    self._answer(c, False, call_failed(c.name, c.args, e))
                else:
                    self._answer(c, True, list(r.driver.pose))
            if isinstance(run.outcome, TaskDone):
                return run.outcome.result
            raise TaskFailed(run.outcome.message, run.outcome.reason, run.outcome.line, run.outcome.traceback)
        finally:
            self.runs.pop(run_id, None)
            if run.outcome is None and self.sb is not None:
                try:
                    self.sb.cancel(run_id)  # interrupted, stopped or bumped: team code gets TaskCancelled
                except RoboCompError:
                    pass

    def _answer_now(self, site: HostSite, c: RpcCall) -> tuple[bool, Any]:
        """Answer a call that takes no time at once (step-locked: the engine's answers to pictures,
        finds and the radio come back before it returns)."""
        box: list[tuple[bool, Any]] = []
        try:
            value = answer_call(site, c.name, list(c.args), lambda ok, v: box.append((ok, v)))
        except Refused as e:
            return False, str(e)
        except RoboCompError as e:
            return False, e.message
        except (TypeError, ValueError, IndexError) as e:
            return False, call_failed(c.name, c.args, e)
        if value is not PENDING:
            return True, value
        if not box:
            return False, f"robot.{c.name} got no answer"
        ok, v = box[0]
        return (True, v) if ok else (False, v if isinstance(v, str) else str((v or {}).get("message", "refused")))

    def _answer(self, c: RpcCall, ok: bool, value: Any) -> None:
        """Send team code the answer to call ``c`` (and tell ``on_answer``)."""
        if self.on_answer is not None:
            self.on_answer(c.tag, c.name, list(c.args), ok, value)
        sb = self.sb
        if sb is None:
            return
        try:
            if ok:
                sb.resolve(c.call_id, value)
            else:
                sb.reject(c.call_id, str(value))
        except RoboCompError:
            pass  # the run ended meanwhile

    def wait_run(self, run_id: int, deadline: float) -> bool:
        """Step-locked: wait (at most until ``deadline``, monotonic) until run ``run_id`` makes a
        call or ends; what the sandbox says meanwhile is taken (other runs' calls wait for their
        turn). False when the deadline passed first."""
        sb = self.sb
        run = self.runs.get(run_id)
        while sb is not None and run is not None and run.call is None and run.outcome is None:
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            for rec in sb.poll(min(0.05, left)):
                self._take(rec)
        return True

    # ------------------------------------------------------------------ the loop
    def pump(self) -> None:
        """Handle everything the sandbox has to say, without blocking."""
        if self.sb is None:
            return
        for rec in self.sb.poll(0.0):
            self._take(rec)
        now = time.monotonic()
        if not self.step_locked and self.canvas.dirty and now >= self.next_draw:  # the engine flushes at its ticks
            self.next_draw = now + drawing.TICK
            self.flush_drawing()

    def flush_drawing(self) -> None:
        """Send the robots' frames of debug drawing that changed to the host (``team_draw``): a
        host does it at most once per :data:`~robo_comp.protocol.drawing.TICK` of real time, the
        engine at each of its position samples (simulated time)."""
        for _team, (tags, frames) in self.canvas.changed().items():
            self.host.team_draw(tags, frames)

    def _take(self, rec: Any) -> None:
        """Act on one record of the sandbox."""
        if isinstance(rec, RpcCall):
            self._call(rec)
        elif isinstance(rec, (TaskDone, SbFailed)):
            run = self.runs.get(rec.run_id)
            if run is not None:
                run.outcome = rec
        elif isinstance(rec, Loaded):
            job = self.loads.pop(rec.load_id, None)
            if job is not None:
                self._answer_load(job, rec.module, None)
        elif isinstance(rec, LoadFailed):
            job = self.loads.pop(rec.load_id, None)
            if job is not None:
                self._answer_load(job, None, rec.error)
        elif isinstance(rec, LogLine):
            self.host.team_log(rec.tag, rec.stream, rec.text)
        elif isinstance(rec, Drawing):
            r = self.host.by_tag.get(rec.tag)
            if r is not None:
                take_drawing(HostSite(self.host, r, self.canvas), rec)
        elif isinstance(rec, SandboxStopped):
            log.warning("team sandbox stopped (%s): %s%s", rec.reason, rec.message,
                        "; restarted with the good modules" if rec.respawned else
                        f"; resting {rec.cooldown:g} s" if rec.cooldown else "")
            self.host.team_log(None, "sandbox", f"sandbox stopped: {rec.message}")
        elif isinstance(rec, SandboxRestarted):
            log.info("team sandbox restarted: %s", rec.message)
            self.host.team_log(None, "sandbox", rec.message)

    def _call(self, c: RpcCall) -> None:
        sb = self.sb
        assert sb is not None
        r = self.host.by_tag.get(c.tag)
        run = self.runs.get(c.run_id)
        try:
            if r is None or run is None:
                raise Refused("this robot is not running that task any more")
            if c.name in MOVEMENT_CALLS or self.step_locked:
                run.call = c  # answered by the run's task generator, in its turn
                return
            site = HostSite(self.host, r)
            value = answer_call(site, c.name, list(c.args), lambda ok, v: self._settle(c.call_id, ok, v))
            if value is not PENDING:
                sb.resolve(c.call_id, value)
        except Refused as e:
            sb.reject(c.call_id, str(e))
        except RoboCompError as e:
            sb.reject(c.call_id, e.message)
        except Exception as e:  # a host bug must not hang team code
            log.exception("robot call %s failed", c.name)
            sb.reject(c.call_id, call_failed(c.name, c.args, e))

    def _settle(self, call_id: int, ok: bool, value: Any) -> None:
        """Answer a call that went to the core, once the core has answered."""
        if self.sb is None:
            return
        try:
            if ok:
                self.sb.resolve(call_id, value)
            else:
                self.sb.reject(call_id, str((value or {}).get("message", "refused by the core")))
        except RoboCompError:
            pass  # the run ended meanwhile


__all__ = ["TeamCode", "CodeRun", "DebugCanvas", "DRAW_CALLS", "LoadJob", "Refused", "CallSite", "HostSite",
           "ROBOT_CALLS", "MOVEMENT_CALLS", "no_settle", "take_drawing",
           "answer_call", "movement_steps", "in_bounds", "free_cell", "move_direction", "plan_path",
           "map_piece", "MAX_PIECE_RADIUS", "MAX_EVIDENCE"]

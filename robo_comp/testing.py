"""The pytest plugin of robo_comp: test team code against a real match or a seeded bench.

Installed with robo_comp (entry point ``pytest11``), so a team package's tests get these
fixtures without a ``conftest.py``:

``robo_scenario``
    Path of the scenario file the tests use: ``--robo-scenario`` on the command line, else the
    ``robo_comp_scenario`` ini option (a path relative to the rootdir, or the name of a bundled
    scenario such as ``demo_room``), else the bundled ``demo_room``.
``robo_team``
    The team the tests play for: ``--robo-team``, else the ``robo_comp_team`` ini option, else
    the scenario's first team.
``robo_match``
    A :class:`Match`: a **real core process** serving the scenario (practice mode: the match is
    running at once) in a temporary state folder. Start robot hosts with
    :meth:`Match.robots`, talk to it with :meth:`Match.client`; everything is stopped at
    teardown.
``robo_bench``
    A :class:`Bench`: the team's modules in the **real sandbox** (:class:`~robo_comp.sandbox.parent.Sandbox`,
    a separate restricted process), its robot API answered by an in-process, seeded simulation
    of the scenario on a step-locked simulated clock. :meth:`Bench.run` runs one task,
    :meth:`Bench.run_match` a whole match (task lists for many robots, a simulated duration; a
    :class:`MatchRun` with the score, the finds and a JSON-lines event log). Deterministic: the
    same code, scenario and seed give the same event log.

Helpers: :func:`wait_for`, :func:`wait_robots`, :func:`next_event_where`; for the template's
explorer on the bench, :func:`sweep_plan` and :func:`report_seen`.

In a real match, upload a module with ``client.upload(tags, filename, source)`` and give its
tasks like any other; on the bench the same module runs without a core.
"""
from __future__ import annotations

import json
import math
import os
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from subprocess import Popen
from typing import TYPE_CHECKING, Any

import pytest

from robo_comp.client import Client
from robo_comp.errors import BadTaskError, FieldError, RoboCompError, UnavailableError, UploadError
from robo_comp.launch import start_core, start_robots, stop_all
from robo_comp.robots import teamcode as host_answers  # the robot host's answers to team code

if TYPE_CHECKING:  # heavy imports (numpy, numba, the sandbox) only when a fixture needs them
    from robo_comp.sandbox.contract import ModuleInfo
    from robo_comp.sandbox.parent import Limits, LogLine
    from robo_comp.world.scenario import Scenario

DEFAULT_SCENARIO = "demo_room"
HEARTBEAT = 0.2


# ---------------------------------------------------------------------- waiting helpers
def wait_for(pred: Callable[[], Any], timeout: float = 10.0, what: str = "condition") -> Any:
    """Poll ``pred`` every 50 ms until it returns a truthy value, and return that value.

    Raises AssertionError naming ``what`` after ``timeout`` seconds.
    """
    t_end = time.monotonic() + timeout
    while True:
        v = pred()
        if v:
            return v
        if time.monotonic() > t_end:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.05)


def wait_robots(client: Client, n: int, status: str = "connected", timeout: float = 30.0) -> list[dict[str, Any]]:
    """Wait until ``client`` sees at least ``n`` robots with ``status``; return those rows by tag."""
    def ready() -> list[dict[str, Any]] | None:
        rows = sorted((r for r in client.robots() if r["status"] == status), key=lambda r: r["tag"])
        return rows if len(rows) >= n else None
    return wait_for(ready, timeout, f"{n} {status} robots")


def next_event_where(client: Client, pred: Callable[[dict[str, Any]], bool],
                     timeout: float = 10.0) -> dict[str, Any]:
    """Read pushed events (after ``client.watch()``) until one satisfies ``pred``; return it.

    Events read before the match are consumed. Raises AssertionError after ``timeout`` s.
    """
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        ev = client.next_event(min(0.2, max(0.0, t_end - time.monotonic())))
        if ev is not None and pred(ev):
            return ev
    raise AssertionError(f"timed out after {timeout} s waiting for a matching event")


def resolve_scenario(spec: str | os.PathLike[str], base: Path | None = None) -> Path:
    """A scenario path from a path (relative to ``base``) or a bundled scenario's name."""
    from robo_comp.world.scenario import bundled_scenario_path

    p = Path(spec)
    if not p.is_absolute() and base is not None:
        p = base / p
    if p.is_file():
        return p.resolve()
    if str(spec).endswith(".toml"):  # a file name, not a bundled scenario's name
        raise FieldError(f"scenario file {spec!r} not found (looked in {p})")
    return bundled_scenario_path(str(spec))


# ---------------------------------------------------------------------- a real match
@dataclass
class Match:
    """A real core process (and the robot hosts started for it) in ``state``.

    Built by :func:`start_match` or the ``robo_match`` fixture; :meth:`close` stops it all.
    """

    state: Path
    scenario: Path | None
    proc: Popen[bytes]
    procs: list[Popen[bytes]] = field(default_factory=list)
    clients: list[Client] = field(default_factory=list)

    def token(self, team: str) -> str:
        """A team's token (``"referee"`` for the referee's), as the core wrote it."""
        path = self.state / ("referee.token" if team == "referee" else f"teams/{team}.token")
        return path.read_text().strip()

    def token_file(self, team: str) -> Path:
        """The token file of ``team`` (what ``--token-file`` takes)."""
        return self.state / ("referee.token" if team == "referee" else f"teams/{team}.token")

    @property
    def teams(self) -> list[str]:
        """The match's team names (from the token files)."""
        return sorted(p.stem for p in (self.state / "teams").glob("*.token"))

    def client(self, team: str, **kw: Any) -> Client:
        """A connected :class:`Client` for ``team`` or ``"referee"`` (closed at teardown)."""
        c = Client(str(self.state), self.token(team), **kw)
        self.clients.append(c)
        return c

    def referee(self) -> Client:
        """A client holding the referee's token."""
        return self.client("referee")

    def robots(self, team: str, count: int = 1, *extra: str, organiser: bool = True,
               speed: float | None = None) -> Popen[bytes]:
        """Start a ``robo-comp robots`` process with ``count`` robots of ``team``.

        ``organiser=True`` passes the scenario file (``--scenario``): the simulated camera then
        shows the hidden victims, as on the organiser's hosts in a match. ``speed`` is in
        cells per second (default: the scenario's). The output goes to ``robots-<team>.log``
        in the state folder.
        """
        args = list(extra)
        if organiser and self.scenario is not None:
            args += ["--scenario", str(self.scenario)]
        if speed is not None:
            args += ["--speed", str(speed)]
        p = start_robots(self.state, team, count, *args)
        self.procs.append(p)
        return p

    def start(self) -> dict[str, Any]:
        """Start the match as the referee (not needed in practice mode, where it runs already)."""
        return self.referee().request("match", action="start")

    def scores(self, team: str = "referee") -> dict[str, Any]:
        """The ``score`` reply: ``teams`` (ranked rows), ``lines`` (the caller's), the clock."""
        c = self._cached(team)
        return c.request("score")

    def score_of(self, team: str) -> float:
        """``team``'s current score."""
        rows = {r["team"]: r for r in self.scores()["teams"]}
        return float(rows[team]["score"])

    def logged_events(self, topic: str | None = None) -> list[dict[str, Any]]:
        """Events the core has written to ``events.log`` so far (optionally of one topic),
        as ``{seq, t, topic, team, data}`` dicts."""
        from robo_comp.protocol.logfile import read_log

        path = self.state / "events.log"
        if not path.exists():
            return []
        return [{"seq": r.seq, "t": r.t, "topic": r.topic, "team": r.team, "data": r.data}
                for r in read_log(path, strict=False) if topic is None or r.topic == topic]

    def log_tail(self, name: str = "core.log", chars: int = 3000) -> str:
        """The end of a process log in the state folder (for assertion messages)."""
        p = self.state / name
        return p.read_text(errors="replace")[-chars:] if p.exists() else ""

    def _cached(self, team: str) -> Client:
        for c in self.clients:
            if c.token == self.token(team) and c.sock is not None:
                return c
        return self.client(team)

    def close(self) -> None:
        """Close the clients and stop every process (robot hosts first)."""
        for c in self.clients:
            c.close()
        self.clients.clear()
        stop_all([self.proc, *self.procs])

    def __enter__(self) -> Match:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def start_match(state: Path, scenario: str | os.PathLike[str] | None = DEFAULT_SCENARIO, *,
                teams: Iterable[str] | None = None, practice: bool = True,
                heartbeat: float = HEARTBEAT, extra: Iterable[str] = ()) -> Match:
    """Start a real core process for ``scenario`` with its state in ``state``.

    ``scenario`` is a path or a bundled name (None: the core's built-in arena).
    ``practice=True`` means no phases: the match runs at once and never ends; with False the
    match waits in ``setup`` until :meth:`Match.start`.
    """
    args = ["--heartbeat", str(heartbeat)]
    path = resolve_scenario(scenario) if scenario is not None else None
    if path is not None:
        args += ["--scenario", str(path)]
    if teams:
        args += ["--teams", ",".join(teams)]
    if practice and path is not None:
        args.append("--practice")
    proc = start_core(state, *args, *extra)
    return Match(state, path, proc)


# ---------------------------------------------------------------------- the in-process bench
class TaskError(AssertionError):
    """A team task failed on the bench (``message``, ``reason`` and ``line`` as the sandbox said)."""

    def __init__(self, message: str, reason: str, line: int | None) -> None:
        super().__init__(message)
        self.message = message
        self.reason = reason
        self.line = line


#: A task for :meth:`Bench.run_match`: ``(name, args)``.
TaskStep = tuple[str, "list[Any] | tuple[Any, ...]"]
#: Robot calls that move the robot: they take simulated time and end at a movement's end.
MOVEMENT_CALLS = ("move", "turn", "go_to")


@dataclass
class MatchRun:
    """What :meth:`Bench.run_match` returns.

    ``events`` is this run's part of the bench's event log (see :meth:`Bench.write_events`),
    ``finds`` the reports judged during the run, ``outcomes`` per robot tag the ``task.done``
    events of its tasks in order, ``sim_seconds`` the simulated time the run took, ``score`` the
    team's score at its end (every run so far counts), ``wall_seconds`` the real time it took.
    """

    score: float
    sim_seconds: float
    wall_seconds: float
    events: list[dict[str, Any]]
    finds: list[dict[str, Any]]
    outcomes: dict[int, list[dict[str, Any]]]

    @property
    def victims(self) -> set[str]:
        """Ids of the victims confirmed during this run."""
        return {f["verdict"]["victim"] for f in self.finds if f["state"] == "confirmed"}

    def event_lines(self) -> list[str]:
        """The events as JSON lines (sorted keys): identical runs give identical lines."""
        return [_json_line(e) for e in self.events]


@dataclass
class _Motion:
    """A movement call in progress: the call to answer and the cells still to drive to."""

    call_id: int
    name: str
    args: list[Any]
    cells: list[tuple[int, int]]
    error: str | None = None  # a cell found blocked on the way (``move``): reject at the end


class Bench:
    """Team modules in the real sandbox, robots simulated in-process from a scenario, on a
    simulated clock that only advances when every robot's team code waits for a movement.

    ``Bench(scenario, team, robots=1, seed=0)`` builds the simulated arena (seeded: the scenario's
    seed plus ``seed``), places ``robots`` robots of ``team`` in its start zone (tags 101, 102, ...)
    and starts a :class:`~robo_comp.sandbox.parent.Sandbox` for them. ``speed`` (cells per
    second) overrides the scenario's robot speed, as ``robo-comp robots --speed`` does.

    :meth:`run` runs one task on one robot and returns its result; :meth:`run_match` runs task
    lists on many robots for a simulated duration and returns a :class:`MatchRun` (score,
    finds, an event log). Both use the same **step-locked** loop:

    * team code runs one robot at a time: a robot's call is answered, then the bench waits for
      that robot's next call (or the end of its task) before it answers another robot, so
      module globals shared by the robots change in the same order every run;
    * calls that take no time (``position``, ``sense``, ``plan``, ``map_piece``, pictures,
      ``report_find``) are answered at once at the current simulated time;
    * the simulated clock advances (steps of ``dt`` seconds, all robots moving together) only when
      every running robot waits for a movement (``move``, ``turn``, ``go_to``); a movement is
      answered at the step where it ends.

    Nothing depends on real time, so the same scenario, seed and code give the same event log.

    What the robot API answers (as the robot host, ``robo_comp/robots/teamcode.py``, answers):

    ===================  =================================================================
    ``move(cells)``      cell by cell along the believed heading; RobotError (the task goes on)
                         when the next cell is a wall or outside; the believed ``[x, y, heading]``
    ``turn(degrees)``    positive = clockwise on screen (the arena's convention); the pose
    ``go_to(x, y)``      the planned path cell by cell; the pose; RobotError for a wall/no path
    ``position()``       believed ``[x, y, heading]`` (positioning noise and drift included)
    ``sense()``          ``{front, left, right, down (cm or None), bump, moving, zone, time}``
    ``plan(x, y)``       ``[[x, y], ...]`` from the robot's cell; RobotError for a wall/no path
    ``map_piece(r)``     ``{"x0", "y0", "walls"}``: rows of 1 (blocked) / 0, r from 0 to 20
    ``take_picture()``   a picture id (the judge knows what the camera saw); ``upload_picture``
                         the same, as on the host
    ``report_find(...)`` judged by the installed scoring rules as the core's ``find``:
                         ``{"id", "state", "message"}``, state ``confirmed``/``rejected``/``duplicate``
    ``radio``            refused (RobotError): no core on the bench
    ===================  =================================================================

    A bump ends the robot's task (``task.done`` not ok, "bumped into ... and stopped") and costs
    the collision penalty, as in a real match. The robot host is the reference: the bench is for
    fast, repeatable tests, a real match (:class:`Match`) for the final word.
    """

    def __init__(self, scenario: str | os.PathLike[str] | Scenario | None = DEFAULT_SCENARIO,
                 team: str | None = None, *, robots: int = 1, seed: int = 0,
                 limits: Limits | None = None, dt: float = 0.05, max_sim_seconds: float = 600.0,
                 speed: float | None = None) -> None:
        from robo_comp.plugins.manager import get_plugin_manager
        from robo_comp.sandbox.parent import Sandbox
        from robo_comp.scoring.board import Scoreboard
        from robo_comp.scoring.config import ScoringConfig
        from robo_comp.world.arena import Arena
        from robo_comp.world.localization import Localization
        from robo_comp.world.scenario import Scenario, default_scenario, load_scenario

        if isinstance(scenario, Scenario):
            sc = scenario
        elif scenario is None:
            sc = default_scenario()
        else:
            sc = load_scenario(resolve_scenario(scenario))
        self.scenario = sc
        teams = [t.name for t in sc.teams] or ["red"]
        self.team = team or teams[0]
        if self.team not in teams:
            raise FieldError(f"the scenario has no team {self.team!r}; its teams are {', '.join(teams)}")
        self.seed = seed
        self.arena = Arena(sc, seed=sc.seed + seed, capacity=max(16, robots))
        if speed:
            self.arena.speed = float(speed)
        self.loc = Localization(self.arena)
        self.dt = dt
        self.max_sim_seconds = max_sim_seconds
        cells = self.arena.free_start_cells(self.team)
        if len(cells) < robots:
            raise FieldError(f"team {self.team}'s start zone has room for {len(cells)} robots, not {robots}")
        self.tags = [101 + i for i in range(robots)]
        for tag, (x, y) in zip(self.tags, cells):
            self.arena.add_robot(str(tag), self.team, x, y, 0.0)
        self.loc.update()
        self.config = ScoringConfig.from_table(sc.scoring)  # as the core does
        self.board = Scoreboard(teams, get_plugin_manager(), self.config)
        self.pictures: dict[int, dict[str, Any]] = {}
        self.examined: dict[str, set[int]] = {}
        self.finds: list[dict[str, Any]] = []
        self.calls: list[tuple[int, str, list[Any]]] = []
        self.logs: list[LogLine] = []
        #: The event log of every run so far (dicts with ``t``, ``topic`` and data; see run_match).
        self.events: list[dict[str, Any]] = []
        self.sandbox: Sandbox = Sandbox(self.team, self.tags, None, limits, seed=seed)
        # the step-locked loop's state
        self._run_tag: dict[int, int] = {}           # run id -> tag
        self._runs: dict[int, int] = {}              # tag -> run id of its running task
        self._task_of: dict[int, tuple[str, list[Any]]] = {}
        self._computing: set[int] = set()            # tags whose team code runs now
        self._motions: dict[int, _Motion] = {}       # tags waiting for a movement
        self._queues: dict[int, deque[TaskStep]] = {}
        self._ended: dict[int, str] = {}             # run id -> why the bench ended it
        self._on_done: Callable[[int, dict[str, Any]], Iterable[TaskStep] | None] | None = None
        self._outcomes: dict[int, list[dict[str, Any]]] = {}

    # ------------------------------------------------------------------ modules and tasks
    def load(self, path: str | os.PathLike[str], source: str | None = None) -> ModuleInfo:
        """Load a team module (a file, or ``source`` under the file name ``path``) through the
        checked contract; raises :class:`~robo_comp.errors.UploadError` when it is refused."""
        p = Path(path)
        text = p.read_text(encoding="utf-8") if source is None else source
        from robo_comp.sandbox.parent import LoadFailed, Loaded, RpcCall

        lid = self.sandbox.begin_load(p.name, text)
        t_end = time.monotonic() + 10.0
        while time.monotonic() < t_end:
            for rec in self.sandbox.poll(0.05):
                if isinstance(rec, RpcCall):
                    self._on_call(rec)  # init(robot)'s robot calls are refused, as on the host
                elif isinstance(rec, Loaded) and rec.load_id == lid:
                    self._drain_logs()
                    return rec.module
                elif isinstance(rec, LoadFailed) and rec.load_id == lid:
                    raise rec.error
                else:
                    self._on_record(rec)
        raise UploadError(f"{p.name}: timeout: no answer from the sandbox", file=p.name, rule="timeout")

    def tasks(self) -> dict[str, dict[str, Any]]:
        """The tasks the loaded modules advertise (``Sandbox.advertised_tasks``)."""
        return self.sandbox.advertised_tasks()

    def run(self, task: str, *args: Any, tag: int | None = None, timeout: float = 60.0) -> Any:
        """Run ``task(robot, *args)`` on robot ``tag`` (the first robot by default) until it ends
        (at most ``max_sim_seconds`` simulated seconds); return its result. Raises
        :class:`TaskError` if the task failed and AssertionError if it did not end."""
        tag = self.tags[0] if tag is None else tag
        out = self.run_match({tag: [(task, list(args))]}, seconds=self.max_sim_seconds, timeout=timeout)
        done = out.outcomes.get(tag, [])
        if not done:
            raise AssertionError(f"task {task} did not finish within {self.max_sim_seconds:g} simulated s")
        d = done[-1]
        if d["ok"]:
            return d["result"]
        if d.get("start_error"):
            raise BadTaskError(d["status"])
        raise TaskError(d["status"], d.get("reason", "error"), d.get("line"))

    def run_match(self, plan: Mapping[int, Iterable[TaskStep]] | TaskStep, *, seconds: float | None = None,
                  on_done: Callable[[int, dict[str, Any]], Iterable[TaskStep] | None] | None = None,
                  timeout: float = 120.0) -> MatchRun:
        """Run tasks on the robots for ``seconds`` of simulated time (default: the scenario's
        ``duration``), or until every robot is idle; return a :class:`MatchRun`.

        ``plan`` maps a robot tag to the tasks it runs one after the other, ``[(name, args), ...]``
        (as ``give --queue`` does in a match); a single ``(name, args)`` runs on every robot.
        ``on_done(tag, outcome)`` is called when a task of ``tag`` ends (``outcome`` is its
        ``task.done`` event: ``ok``, ``status``, ``result``); the tasks it returns run next on
        that robot (before the rest of its list) -- use it for what a team does between tasks (it must be deterministic
        for the run to be). Tasks still running when the time is up are cancelled.
        ``timeout`` bounds the *real* time the run may take (a safety net).
        The run continues the bench's clock, score and log: call it again to go on.
        """
        t0 = time.monotonic()
        if isinstance(plan, tuple):
            plan = {tag: [plan] for tag in self.tags}
        seconds = float(self.scenario.duration if seconds is None else seconds)
        start_time = self.arena.time
        t_end = start_time + seconds
        first_event, first_find = len(self.events), len(self.finds)
        self._on_done = on_done
        self._outcomes = {tag: [] for tag in self.tags}
        for tag, steps in plan.items():
            if tag not in self.tags:
                raise FieldError(f"robot {tag} is not on the bench; its robots are {self.tags}")
            self._queues.setdefault(tag, deque()).extend((str(n), list(a)) for n, a in steps)
        self._wall_end = t0 + timeout
        self._drain_logs()
        ready = sorted(t for t in self.tags if self._queues.get(t))
        while True:
            for tag in ready:
                self._serve(tag)
            if not self._motions or self.arena.time >= t_end - 1e-9:
                break
            ready = self._advance(t_end)
        self._finish("time is up")
        return MatchRun(score=self.score(), sim_seconds=round(self.arena.time - start_time, 6),
                        wall_seconds=time.monotonic() - t0, events=self.events[first_event:],
                        finds=self.finds[first_find:], outcomes=self._outcomes)

    def log_text(self) -> str:
        """Everything the team code printed or logged, in order."""
        return "".join(line.text for line in self.logs)

    def score(self) -> float:
        """The team's score so far (victims found minus penalties)."""
        return self.board.score_of(self.team)

    def true_cell(self, tag: int | None = None) -> tuple[int, int]:
        """Where the robot really is (the arena's ground truth, rounded to a cell)."""
        p = self.arena.pose(str(self.tags[0] if tag is None else tag))
        return int(round(p.x)), int(round(p.y))

    def write_events(self, path: str | os.PathLike[str]) -> Path:
        """Write the event log as JSON lines (sorted keys); returns the path."""
        p = Path(path)
        p.write_text("".join(_json_line(e) + "\n" for e in self.events), encoding="utf-8")
        return p

    def close(self) -> None:
        """Stop the sandbox process."""
        self.sandbox.close()

    def __enter__(self) -> Bench:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ the step-locked loop
    def _event(self, topic: str, tag: int | None = None, **data: Any) -> None:
        self.events.append({"t": round(self.arena.time, 6), "topic": topic, "tag": tag, **data})

    def _serve(self, tag: int) -> None:
        """Let robot ``tag`` go on at the current simulated time until it waits for a movement or
        has nothing left to do: answer its finished movement or start its next task, then answer
        its calls as they come."""
        m = self._motions.get(tag)
        if m is not None and not m.cells and not self.arena.is_moving(str(tag)):
            del self._motions[tag]
            if m.error is not None:
                self._reject(tag, m.call_id, m.name, m.args, m.error)
            else:
                self._resolve(tag, m.call_id, m.name, m.args, list(self._pose_raw(str(tag))))
        elif tag not in self._runs:
            self._start_next(tag)
        while tag in self._computing:
            self._handle_records()

    def _handle_records(self) -> None:
        """Wait (a little) for what the sandbox says and act on it."""
        from robo_comp.sandbox.parent import RpcCall

        recs = self.sandbox.poll(0.05)
        if not recs and time.monotonic() > self._wall_end:
            raise AssertionError("the bench ran out of real time (run_match timeout): team code "
                                 f"of robots {sorted(self._computing)} did not answer")
        for rec in recs:
            if isinstance(rec, RpcCall):
                self._on_call(rec)
            else:
                self._on_record(rec)

    def _start_next(self, tag: int) -> None:
        q = self._queues.get(tag)
        while q:
            name, args = q.popleft()
            try:
                rid = self.sandbox.start_task(tag, name, args)
            except RoboCompError as e:
                self._task_done(tag, {"ok": False, "status": e.message, "result": None, "task": name,
                                      "start_error": True})
                continue
            self._runs[tag] = rid
            self._run_tag[rid] = tag
            self._task_of[tag] = (name, args)
            self._computing.add(tag)
            self._event("task.start", tag, task=name, args=args)
            return

    def _task_done(self, tag: int, outcome: dict[str, Any]) -> None:
        self._event("task.done", tag, **outcome)
        ev = self.events[-1]
        self._outcomes.setdefault(tag, []).append(ev)
        if self._on_done is not None:
            more = self._on_done(tag, ev)
            if more:  # what the team gives now runs before the robot's queue
                self._queues.setdefault(tag, deque()).extendleft((str(n), list(a)) for n, a in reversed(list(more)))
        self._start_next(tag)

    def _on_record(self, rec: Any) -> None:
        from robo_comp.sandbox.parent import LogLine, SandboxStopped, TaskDone, TaskFailed as SbFailed

        if isinstance(rec, LogLine):
            self.logs.append(rec)
            self._event("robot.log", rec.tag, stream=rec.stream, text=rec.text)
        elif isinstance(rec, (TaskDone, SbFailed)):
            tag = self._run_tag.pop(rec.run_id, None)
            if tag is None or self._runs.get(tag) != rec.run_id:
                return
            del self._runs[tag]
            self._computing.discard(tag)
            self._motions.pop(tag, None)
            name, _ = self._task_of.pop(tag)
            why = self._ended.pop(rec.run_id, None)
            if isinstance(rec, TaskDone) and why is None:
                out = {"ok": True, "status": "done", "result": _plain_tree(rec.result)}
            else:
                out = {"ok": False, "status": why or rec.message, "result": None,
                       "reason": "stopped" if why else rec.reason,
                       "line": None if why else rec.line}  # type: ignore[union-attr]  -- rec is a TaskFailed when why is empty
            self._task_done(tag, dict(out, task=name))
        elif isinstance(rec, SandboxStopped):
            self._event("sandbox.stopped", None, reason=rec.reason, message=rec.message)

    def _on_call(self, c: Any) -> None:
        tag = self._run_tag.get(c.run_id)
        if tag is None or self._runs.get(tag) != c.run_id:
            self.sandbox.reject(c.call_id, "this robot is not running that task any more")
            return
        self.calls.append((tag, c.name, list(c.args)))
        t = str(tag)
        try:
            if c.name in MOVEMENT_CALLS:
                self._begin_motion(tag, c)
                return
            value = self._immediate(t, c.name, list(c.args))
        except (RoboCompError, host_answers.Refused) as e:
            self._reject(tag, c.call_id, c.name, c.args, getattr(e, "message", None) or str(e))
            return
        except (TypeError, ValueError, IndexError) as e:
            self._reject(tag, c.call_id, c.name, c.args, host_answers.call_failed(c.name, c.args, e))
            return
        self._resolve(tag, c.call_id, c.name, c.args, value)

    def _resolve(self, tag: int, call_id: int, name: str, args: list[Any], value: Any) -> None:
        value = _plain_tree(value)
        self._event("call", tag, name=name, args=list(args), ok=True, answer=value)
        self.sandbox.resolve(call_id, value)
        self._computing.add(tag)

    def _reject(self, tag: int, call_id: int, name: str, args: list[Any], message: str) -> None:
        self._event("call", tag, name=name, args=list(args), ok=False, error=message)
        self.sandbox.reject(call_id, message)
        self._computing.add(tag)

    def _begin_motion(self, tag: int, c: Any) -> None:
        """A movement call: the cells to drive to (computed as the host's steps are)."""
        t = str(tag)
        self._computing.discard(tag)
        if c.name == "turn":
            m = _Motion(c.call_id, c.name, list(c.args), [])
            self._motions[tag] = m
            self.arena.command(t, "turn", float(c.args[0]))
            return
        if c.name == "move":
            m = _Motion(c.call_id, c.name, list(c.args), [])
            cells = int(c.args[0])
            dx, dy = host_answers.move_direction(self._pose_raw(t)[2])
            sign = 1 if cells >= 0 else -1
            m.cells = [(sign * dx, sign * dy)] * abs(cells)  # relative: checked cell by cell
            self._motions[tag] = m
            self._next_cell(tag, m)
            return
        path = host_answers.plan_path(self.arena.walls, self._free_cell(t), (int(c.args[0]), int(c.args[1])))
        m = _Motion(c.call_id, c.name, list(c.args), [(int(x), int(y)) for x, y in path[1:]])
        self._motions[tag] = m
        self._next_cell(tag, m)

    def _next_cell(self, tag: int, m: _Motion) -> None:
        """Command the next cell of a movement (a ``move`` checks it first, as the host does)."""
        if not m.cells:
            return
        t = str(tag)
        if m.name == "move":
            dx, dy = m.cells.pop(0)
            x, y = self._cell(t)
            nx, ny = x + dx, y + dy
            if not self._in_bounds(nx, ny):
                m.cells = []
                m.error = f"({nx}, {ny}) is a wall or outside the arena; stopped at ({x}, {y})"
                return
        else:
            nx, ny = m.cells.pop(0)
        self.arena.command(t, "goto", (nx, ny))

    def _advance(self, t_end: float) -> list[int]:
        """Step the arena until a movement ends (or the time is up); returns the robots to serve."""
        while self.arena.time < t_end - 1e-9:
            bumped: dict[int, dict[str, Any]] = {}
            for ev in self.arena.step(min(self.dt, t_end - self.arena.time)):
                tag = int(ev.tag)
                if ev.kind == "bump":
                    other = ev.data.get("other")
                    self._event("robot.bump", tag, x=ev.data["x"], y=ev.data["y"], what=ev.data["what"],
                                other=int(other) if other else None)
                    self._score({"kind": "robot.bump", "team": self.team, "tag": tag})
                    bumped[tag] = ev.data
                elif ev.kind == "zone":
                    self._event("zone", tag, kind=ev.data["kind"], x=ev.data["x"], y=ev.data["y"])
            self.loc.update()
            ready = []
            for tag in sorted(self._motions):
                if tag in bumped and tag in self._runs:
                    b = bumped[tag]
                    other = b.get("other")
                    self._stop_run(tag, host_answers.stop_status(b, f"robot {other}" if other else None))
                    ready.append(tag)
                    continue
                if self.arena.is_moving(str(tag)):
                    continue
                m = self._motions[tag]
                self._next_cell(tag, m)
                if not self.arena.is_moving(str(tag)) and not m.cells:
                    ready.append(tag)
            if ready:
                return ready
        return []

    def _stop_run(self, tag: int, why: str) -> None:
        """End robot ``tag``'s task as the host does (a bump, the end of the match): halt and
        cancel its run; the cancelled run's end is awaited so the next robot finds team code still."""
        self.arena.command(str(tag), "halt")
        self._motions.pop(tag, None)
        rid = self._runs.get(tag)
        if rid is None:
            return
        self._ended[rid] = why
        self.sandbox.cancel(rid)
        self._computing.add(tag)
        while tag in self._computing:
            self._handle_records()

    def _finish(self, why: str) -> None:
        """The time is up: cancel what still runs (in tag order), drop the queues."""
        self._on_done = None
        for q in self._queues.values():
            q.clear()
        for tag in sorted(self._runs):
            self._stop_run(tag, why)
        self._event("match.end", None, score=self.score(),
                    victims=sorted(self.board.found.get(self.team, set())))

    def _drain_logs(self) -> None:
        for rec in self.sandbox.poll(0.0):
            if type(rec).__name__ == "RpcCall":
                self._on_call(rec)
            else:
                self._on_record(rec)

    def _score(self, event: dict[str, Any]) -> None:
        for ln in self.board.apply(event, self.arena.time):
            self._event("score.change", None, team=ln.team, points=ln.points, kind=ln.kind,
                        reason=ln.reason, victim=ln.victim)

    # ------------------------------------------------------------------ the robot API
    def _pose_raw(self, t: str) -> tuple[float, float, float]:
        x, y, h = self.loc.estimate(t)
        return float(x), float(y), float(h)

    def _cell(self, t: str) -> tuple[int, int]:
        x, y, _ = self._pose_raw(t)
        return int(round(x)), int(round(y))

    def _in_bounds(self, x: int, y: int) -> bool:
        return host_answers.in_bounds(self.arena.walls, x, y)

    def _free_cell(self, t: str) -> tuple[int, int]:
        """The free cell the robot believes it is in (as ``SimRobot.free_cell`` on the host)."""
        x, y, _ = self._pose_raw(t)
        return host_answers.free_cell(self.arena.walls, x, y)

    def _immediate(self, t: str, name: str, args: list[Any]) -> Any:
        if name == "position":
            return [round(v, 3) for v in self._pose_raw(t)]
        if name == "sense":
            return {k: _plain(v) for k, v in self.arena.sense(t).items()}
        if name == "plan":
            path = host_answers.plan_path(self.arena.walls, self._free_cell(t), (int(args[0]), int(args[1])))
            return [[int(x), int(y)] for x, y in path]
        if name == "map_piece":
            return host_answers.map_piece(self.arena.walls, *self._cell(t), int(args[0]))
        if name in ("take_picture", "upload_picture"):
            return self._picture(t)
        if name == "report_find":
            x, y, kind, evidence = (list(args) + [None, None, None, None])[:4]
            return self._find(t, x, y, kind, evidence)
        raise UnavailableError(f"the bench does not simulate {name!r} (no core, no radio)")

    def _picture(self, t: str) -> int:
        """A picture at the true pose; the victims in view count as examined (as the core does)."""
        from robo_comp.world.visibility import in_view

        p = self.arena.pose(t)
        cam = self.scenario.camera
        victims = list(self.arena.victims)
        seen = in_view(self.arena.walls, [(v.x, v.y) for v in victims], p.x, p.y, p.heading, cam.fov, cam.range)
        pid = len(self.pictures) + 1
        ids = [v.id for v, f in zip(victims, seen) if f]
        self.pictures[pid] = {"id": pid, "tag": int(t), "x": float(p.x), "y": float(p.y),
                              "heading": float(p.heading), "victims": ids}
        for vid in ids:
            self.examined.setdefault(vid, set()).add(pid)
        self._event("picture", int(t), id=pid, x=float(p.x), y=float(p.y), heading=float(p.heading), victims=ids)
        return pid

    def _find(self, t: str, x: Any, y: Any, kind: Any, evidence: Any) -> dict[str, Any]:
        ev = [int(e) for e in (evidence or [])][:host_answers.MAX_EVIDENCE]  # as the host passes it on
        for pid in ev:
            if pid not in self.pictures:
                raise FieldError(f"picture {pid} is not one of team {self.team}'s pictures")
        find = {"team": self.team, "tag": int(t), "x": float(x), "y": float(y), "kind": str(kind or "victim")[:32],
                "evidence": ev}
        victims = [{"id": v.id, "x": v.x, "y": v.y, "kind": v.kind, "points": v.points} for v in self.arena.victims]
        verdict = self.board.judge(find, {"victims": victims, "examined": self.examined})
        fid = len(self.finds) + 1
        state = "confirmed" if verdict["valid"] else ("duplicate" if verdict.get("duplicate") else "rejected")
        self.finds.append(dict(find, id=fid, state=state, verdict=verdict, t=round(self.arena.time, 6)))
        self._event("find.reported", int(t), id=fid, x=find["x"], y=find["y"], kind=find["kind"], state=state,
                    evidence=ev, message=verdict["reason"])
        self._score({"kind": "find.judged", "team": self.team, "tag": int(t), "verdict": verdict})
        return {"id": fid, "state": state, "message": verdict["reason"]}


def _json_line(event: dict[str, Any]) -> str:
    return json.dumps(event, sort_keys=True, separators=(",", ":"), default=repr)


def _plain_tree(v: Any) -> Any:
    """Plain data all the way down (numpy scalars as Python numbers, tuples as lists)."""
    if isinstance(v, dict):
        return {k: _plain_tree(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain_tree(x) for x in v]
    return _plain(v)

def _plain(v: Any) -> Any:
    """numpy scalars and other number-likes as plain Python values (msgpack-safe)."""
    if v is None or isinstance(v, (bool, str, int)):
        return v
    if isinstance(v, float):
        return None if math.isnan(v) else v
    if hasattr(v, "item"):
        return _plain(v.item())
    return v


# ---------------------------------------------------------------------- plans for the explorer
def sweep_plan(bench: Bench, spacing: int = 6, task: str = "explore") -> dict[int, list[TaskStep]]:
    """A plan that covers the map with the template's explorer: the free cells of a grid of
    ``spacing`` cells, in serpentine row order, cut into one band per robot; each cell is one
    ``explore([[x, y]])`` task. Uses the map only (what every team knows)."""
    walls = bench.arena.walls
    h, w = walls.shape
    rows = []
    for i, y in enumerate(range(spacing // 2, h, spacing)):
        xs = [x for x in range(spacing // 2, w, spacing) if not walls[y, x]]
        rows.extend([x, y] for x in (xs if i % 2 == 0 else xs[::-1]))
    n = len(bench.tags)
    size = max(1, math.ceil(len(rows) / n))
    return {tag: [(task, [[p]]) for p in rows[i * size:(i + 1) * size]] for i, tag in enumerate(bench.tags)}


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


# ---------------------------------------------------------------------- pytest hooks and fixtures
def pytest_addoption(parser: pytest.Parser) -> None:
    """``--robo-scenario`` / ``--robo-team`` and their ini forms."""
    group = parser.getgroup("robo_comp", "robo_comp match and bench fixtures")
    group.addoption("--robo-scenario", default=None,
                    help="scenario file (or bundled scenario name) for robo_match/robo_bench")
    group.addoption("--robo-team", default=None, help="the team robo_bench plays for")
    parser.addini("robo_comp_scenario", "scenario file or bundled name for the robo_comp fixtures",
                  default=DEFAULT_SCENARIO)
    parser.addini("robo_comp_team", "team name for the robo_comp fixtures (default: the scenario's first)",
                  default="")


def pytest_configure(config: pytest.Config) -> None:
    """Register the ``slow`` marker used by team tests that run a real match."""
    config.addinivalue_line("markers", "slow: long-running tests (deselect with -m 'not slow')")


@pytest.fixture(scope="session")
def robo_scenario(pytestconfig: pytest.Config) -> Path:
    """The scenario file the robo_comp fixtures use (see the module docstring)."""
    spec = pytestconfig.getoption("--robo-scenario") or pytestconfig.getini("robo_comp_scenario") or DEFAULT_SCENARIO
    return resolve_scenario(spec, Path(str(pytestconfig.rootpath)))


@pytest.fixture(scope="session")
def robo_team(pytestconfig: pytest.Config, robo_scenario: Path) -> str:
    """The team the tests play for."""
    name = pytestconfig.getoption("--robo-team") or pytestconfig.getini("robo_comp_team")
    if name:
        return str(name)
    from robo_comp.world.scenario import load_scenario

    teams = [t.name for t in load_scenario(robo_scenario).teams]
    return teams[0] if teams else "red"


@pytest.fixture
def robo_match(tmp_path: Path, robo_scenario: Path) -> Iterator[Match]:
    """A real core process serving ``robo_scenario`` in practice mode (stopped at teardown)."""
    m = start_match(tmp_path / "state", robo_scenario)
    try:
        yield m
    finally:
        m.close()


@pytest.fixture
def robo_bench(robo_scenario: Path, robo_team: str) -> Iterator[Bench]:
    """A :class:`Bench` with one robot of ``robo_team`` on ``robo_scenario`` (seed 0)."""
    b = Bench(robo_scenario, robo_team)
    try:
        yield b
    finally:
        b.close()


__all__ = ["Bench", "DEFAULT_SCENARIO", "Match", "MatchRun", "TaskError", "next_event_where", "resolve_scenario",
           "report_seen", "start_match", "sweep_plan", "wait_for", "wait_robots"]

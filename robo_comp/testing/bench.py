"""The seeded, step-locked bench: team code in the real sandbox, robots simulated in-process.

One engine for tests and the league: the bench answers team code through the robot host's own
call table (:mod:`robo_comp.robots.teamcode`: ``ROBOT_CALLS``, ``movement_steps``), judges
pictures and finds with the core's own judge (:class:`robo_comp.scoring.judge.FindJudge`), and
logs the core's event names. :meth:`Bench.write_log` writes the match as a core event log, which
``robo-comp replay``, the wall and the consoles show like any recorded match.
"""
from __future__ import annotations

import json
import math
import os
import time
from collections import deque
from collections.abc import Callable, Generator, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from robo_comp.errors import BadTaskError, FieldError, RoboCompError, UnavailableError, UploadError
from robo_comp.protocol.topics import EVERYONE, TOPICS
from robo_comp.robots import teamcode as host_answers  # the robot host's answers to team code
from robo_comp.robots.steps import Move, Plan, Step, Turn
from robo_comp.sandbox.parent import PENDING
from robo_comp.testing.match import DEFAULT_SCENARIO, resolve_scenario
from robo_comp.testing.usage import EntrantMeter

if TYPE_CHECKING:  # heavy imports (numpy, numba, the sandbox) only when a fixture needs them
    from robo_comp.sandbox.contract import ModuleInfo
    from robo_comp.sandbox.parent import Limits, LogLine, Sandbox
    from robo_comp.world.scenario import Scenario


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
MOVEMENT_CALLS = host_answers.MOVEMENT_CALLS
#: Seconds of simulated time between two logged samples of every robot's true pose.
POSE_SAMPLE = 0.5
#: Calls that take no time one robot may make at once (the call budget's burst; see :class:`Budget`).
CALL_BURST = 100
#: Robot calls that take a picture: each costs :attr:`Budget.picture_cost` calls of the budget.
PICTURE_CALLS = frozenset({"take_picture", "upload_picture", "look"})


@dataclass(frozen=True)
class Budget:
    """What one robot, and one entrant, may ask of a match.

    Every robot call that takes no time draws on the robot's **call budget**, a bucket of
    ``call_burst`` calls refilled at ``calls_per_second`` per *simulated* second (a picture
    costs ``picture_cost`` calls); a call the bucket cannot pay is answered when the simulated
    clock has refilled it, so code that never moves cannot hold up the clock, and code that
    floods (pictures between every two moves) gets no more per simulated second than the
    budget. On a host every call takes real time; this is its simulated price.

    The other limits are per **entrant** (team) and per match; None: no limit. Going over one
    ends the match as that entrant's forfeit (:attr:`Bench.forfeit`): ``events`` (events its
    robots caused), ``log_bytes`` (their size, as JSON lines), ``cpu_seconds`` (CPU time of
    its sandbox's processes), ``wall_seconds`` (real time the match waited for its code: a
    backstop, it grows with the machine's load) and ``memory_mib`` (its sandbox's growth plus
    this process's growth while its robots were served); see :mod:`robo_comp.testing.usage`.
    """

    calls_per_second: float = 10.0
    call_burst: float = CALL_BURST
    picture_cost: float = 4.0
    events: int | None = None
    log_bytes: int | None = None
    wall_seconds: float | None = None
    memory_mib: float | None = None
    cpu_seconds: float | None = None


@dataclass(frozen=True)
class Forfeit:
    """Why a match ended early: ``team`` went over ``limit`` (``events``, ``log_bytes``,
    ``cpu_seconds``, ``wall_seconds``, ``memory_mib``); ``message`` says it to the student; ``t`` is the
    simulated time."""

    team: str
    limit: str
    message: str
    t: float


@dataclass
class MatchRun:
    """What :meth:`Bench.run_match` returns.

    ``events`` is this run's part of the bench's event log (see :meth:`Bench.write_events`),
    ``finds`` the reports judged during the run, ``outcomes`` per robot tag the ``task.done``
    events of its tasks in order, ``sim_seconds`` the simulated time the run took, ``score`` the
    first team's score at its end and ``scores`` every team's (every run so far counts),
    ``wall_seconds`` the real time it took.
    """

    score: float
    sim_seconds: float
    wall_seconds: float
    events: list[dict[str, Any]]
    finds: list[dict[str, Any]]
    outcomes: dict[int, list[dict[str, Any]]]
    scores: dict[str, float]

    @property
    def victims(self) -> set[str]:
        """Ids of the victims confirmed during this run."""
        return {f["verdict"]["victim"] for f in self.finds if f["state"] == "confirmed"}

    def event_lines(self) -> list[str]:
        """The events as JSON lines (sorted keys): identical runs give identical lines."""
        return [_json_line(e) for e in self.events]


@dataclass
class _Motion:
    """A movement call in progress: the call to answer and the host's movement steps."""

    call_id: int
    name: str
    args: list[Any]
    steps: Generator[Step, Any, Any]
    done: bool = False
    error: str | None = None  # the steps refused (a wall ahead, no path): reject at the end
    answer: tuple[bool, Any] | None = None  # a call held back by the call budget: its answer
    until: float = 0.0  # ... answered at this simulated time


def _no_steps() -> Generator[Step, Any, Any]:
    """The steps of a call that only waits for the next clock step."""
    return
    yield


class _BenchSite:
    """One bench robot as the host's :class:`~robo_comp.robots.teamcode.CallSite`."""

    def __init__(self, bench: Bench, tag: int) -> None:
        self.bench = bench
        self.tag = tag
        self.walls = bench.arena.walls

    def pose(self) -> tuple[float, float, float]:
        x, y, h = self.bench.loc.estimate(str(self.tag))
        return float(x), float(y), float(h)

    def cell(self) -> tuple[int, int]:
        x, y, _ = self.pose()
        return int(round(x)), int(round(y))

    def free_cell(self) -> tuple[int, int]:
        x, y, _ = self.pose()
        return host_answers.free_cell(self.walls, x, y)

    def sense(self) -> dict[str, Any]:
        return {k: _plain(v) for k, v in self.bench.arena.sense(str(self.tag)).items()}

    def picture(self, on_reply: host_answers.Reply) -> None:
        rec = self.bench._picture(self.tag)
        on_reply(True, {"id": rec["id"], "seen": self.bench.judge.describe(rec["victims"])})

    def request(self, type_: str, body: dict[str, Any], on_reply: host_answers.Reply) -> None:
        if type_ != "find":
            raise UnavailableError(f"the bench does not simulate {type_!r} (no core, no radio)")
        try:
            answer = self.bench._find(self.tag, body)
        except RoboCompError as e:
            on_reply(False, {"message": e.message})
            return
        on_reply(True, answer)


class Bench:
    """Team modules in the real sandbox, robots simulated in-process from a scenario, on a
    simulated clock that only advances when every robot's team code waits for a movement.

    ``Bench(scenario, team, robots=1, seed=0)`` builds the simulated arena (seeded: the scenario's
    seed plus ``seed``), places ``robots`` robots of ``team`` in its start zone (tags 101, 102, ...)
    and starts a :class:`~robo_comp.sandbox.parent.Sandbox` for them. ``teams={"red": 4, "blue": 4}``
    plays several teams instead, each with its own sandbox (the n-th team's tags start at
    ``100 * n + 1``). ``speed`` (cells per second) overrides the scenario's robot speed, as
    ``robo-comp robots --speed`` does.

    :meth:`run` runs one task on one robot and returns its result; :meth:`run_match` runs task
    lists on many robots for a simulated duration and returns a :class:`MatchRun` (scores,
    finds, an event log). Both use the same **step-locked** loop:

    * team code runs one robot at a time: a robot's call is answered, then the bench waits for
      that robot's next call (or the end of its task) before it answers another robot, so
      module globals shared by the robots change in the same order every run;
    * calls that take no time (``position``, ``sense``, ``plan``, ``map_piece``, pictures,
      ``look``, ``report_find``) are answered at once at the current simulated time while the
      robot's call budget (:class:`Budget`: :data:`CALL_BURST` at once, refilled per simulated
      second) pays for them; past it, each is answered when the budget has refilled (code that
      never moves cannot stop the clock);
    * the simulated clock advances (steps of ``dt`` seconds, all robots moving together) only when
      every running robot waits for a movement (``move``, ``turn``, ``go_to``); a movement is
      answered at the step where it ends.

    Nothing depends on real time, so the same scenario, seed and code give the same event log.

    The robot API is answered by the robot host's own table
    (:data:`robo_comp.robots.teamcode.ROBOT_CALLS` and ``movement_steps``): the same checks, the
    same paths, the same messages. Pictures and finds are judged by the core's
    :class:`~robo_comp.scoring.judge.FindJudge` with the installed scoring rules. ``radio`` is
    refused (RobotError): no core on the bench.

    A bump ends the robot's task (``task.done`` not ok, "bumped into ... and stopped") and costs
    the collision penalty, as in a real match. Events carry the core's topics (``task.started``,
    ``task.done``, ``picture``, ``find.reported``, ``score.change``, ``robot.bump``,
    ``robot.log``, ``robot.positions``, ``match.phase``) plus two of the bench's own,
    ``robot.call`` (each answered call) and ``robot.zone`` (a robot entering a zone).
    """

    def __init__(self, scenario: str | os.PathLike[str] | Scenario | None = DEFAULT_SCENARIO,
                 team: str | None = None, *, robots: int = 1, seed: int = 0,
                 limits: Limits | None = None, dt: float = 0.05, max_sim_seconds: float = 600.0,
                 speed: float | None = None, teams: Mapping[str, int] | None = None,
                 pose_sample: float = POSE_SAMPLE, budget: Budget | None = None) -> None:
        from robo_comp.plugins.manager import get_plugin_manager
        from robo_comp.sandbox.parent import Sandbox
        from robo_comp.scoring.board import Scoreboard
        from robo_comp.scoring.config import ScoringConfig
        from robo_comp.scoring.judge import FindJudge
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
        names = [t.name for t in sc.teams] or ["red"]
        playing = dict(teams) if teams else {team or names[0]: robots}
        for name in playing:
            if name not in names:
                raise FieldError(f"the scenario has no team {name!r}; its teams are {', '.join(names)}")
        self.team = next(iter(playing))
        self.teams = list(playing)
        self.seed = seed
        total = sum(playing.values())
        self.arena = Arena(sc, seed=sc.seed + seed, capacity=max(16, total))
        if speed:
            self.arena.speed = float(speed)
        self.loc = Localization(self.arena)
        self.dt = dt
        self.max_sim_seconds = max_sim_seconds
        self.pose_sample = pose_sample
        self.tags_of: dict[str, list[int]] = {}
        self.team_of: dict[int, str] = {}
        for n, (name, count) in enumerate(playing.items(), start=1):
            cells = self.arena.free_start_cells(name)
            if len(cells) < count:
                raise FieldError(f"team {name}'s start zone has room for {len(cells)} robots, not {count}")
            tags = [100 * n + 1 + i for i in range(count)]
            self.tags_of[name] = tags
            for tag, (x, y) in zip(tags, cells):
                self.arena.add_robot(str(tag), name, x, y, 0.0)
                self.team_of[tag] = name
        self.tags = [t for name in self.teams for t in self.tags_of[name]]
        self.loc.update()
        self._start = {tag: self._true_pose(tag) for tag in self.tags}
        self.config = ScoringConfig.from_table(sc.scoring)  # as the core does
        self.board = Scoreboard(names, get_plugin_manager(), self.config)
        self.judge = FindJudge(sc, names, self.board)
        self.finds: list[dict[str, Any]] = []
        self.calls: list[tuple[int, str, list[Any]]] = []
        self.logs: list[LogLine] = []
        #: The event log of every run so far (dicts with ``t``, ``topic``, ``team`` and the
        #: event's data; see run_match).
        self.events: list[dict[str, Any]] = []
        self.sandboxes: dict[str, Sandbox] = {
            name: Sandbox(name, self.tags_of[name], None, limits, seed=seed, deterministic=True) for name in self.teams}
        self.sandbox: Sandbox = self.sandboxes[self.team]
        # the step-locked loop's state
        self._run_tag: dict[tuple[str, int], int] = {}  # (team, run id) -> tag
        self._runs: dict[int, int] = {}              # tag -> run id of its running task
        self._task_of: dict[int, tuple[int, str, list[Any]]] = {}  # tag -> task id, name, args
        self._computing: set[int] = set()            # tags whose team code runs now
        self._motions: dict[int, _Motion] = {}       # tags waiting for a movement
        self._queues: dict[int, deque[TaskStep]] = {}
        self._ended: dict[tuple[str, int], str] = {}  # (team, run id) -> why the bench ended it
        self._on_done: Callable[[int, dict[str, Any]], Iterable[TaskStep] | None] | None = None
        self._outcomes: dict[int, list[dict[str, Any]]] = {}
        self._next_task = 1
        self.budget = budget or Budget()
        self._tokens: dict[int, tuple[float, float]] = {}  # tag -> (calls left, at simulated time)
        #: Per team: events its robots caused, their bytes as JSON lines, real seconds the match
        #: waited for its code and the CPU seconds its code used.
        self.used: dict[str, dict[str, float]] = {t: {"events": 0.0, "log_bytes": 0.0, "wall_seconds": 0.0,
                                                      "cpu_seconds": 0.0}
                                                  for t in self.teams}
        #: Set when an entrant went over a match limit; the match then ends (see :class:`Budget`).
        self.forfeit: Forfeit | None = None
        self.meter = EntrantMeter(self.sandboxes)  # CPU, real time, memory per entrant (the match limits)
        self._ending: str | None = None  # the entrant whose forfeit is ending the match
        self._next_memory_check = 0
        self._next_sample = 0.0
        self._wall_end = math.inf

    # ------------------------------------------------------------------ what the match holds
    @property
    def pictures(self) -> dict[int, dict[str, Any]]:
        """Every picture taken (the judge's records: ``id``, ``tag``, ``team``, pose, ``victims``)."""
        return self.judge.pictures

    @property
    def examined(self) -> dict[str, set[int]]:
        """The first team's examined victims: victim id -> the ids of pictures showing it."""
        return self.judge.examined.setdefault(self.team, {})

    # ------------------------------------------------------------------ modules and tasks
    def load(self, path: str | os.PathLike[str], source: str | None = None, *, team: str | None = None) -> ModuleInfo:
        """Load a team module (a file, or ``source`` under the file name ``path``) into ``team``'s
        sandbox (default: the first team) through the checked contract; raises
        :class:`~robo_comp.errors.UploadError` when it is refused."""
        p = Path(path)
        text = p.read_text(encoding="utf-8") if source is None else source
        from robo_comp.sandbox.parent import LoadFailed, Loaded, RpcCall

        name = team or self.team
        sb = self.sandboxes[name]
        lid = sb.begin_load(p.name, text)
        t_end = time.monotonic() + 10.0
        while time.monotonic() < t_end:
            for rec in sb.poll(0.05):
                if isinstance(rec, RpcCall):
                    self._on_call(name, rec)  # init(robot)'s robot calls are refused, as on the host
                elif isinstance(rec, Loaded) and rec.load_id == lid:
                    self._drain_logs()
                    return rec.module
                elif isinstance(rec, LoadFailed) and rec.load_id == lid:
                    raise rec.error
                else:
                    self._on_record(name, rec)
        raise UploadError(f"{p.name}: timeout: no answer from the sandbox", file=p.name, rule="timeout")

    def tasks(self, team: str | None = None) -> dict[str, dict[str, Any]]:
        """The tasks the loaded modules of ``team`` (default: the first) advertise."""
        return self.sandboxes[team or self.team].advertised_tasks()

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
            if tag not in self.team_of:
                raise FieldError(f"robot {tag} is not on the bench; its robots are {self.tags}")
            self._queues.setdefault(tag, deque()).extend((str(n), list(a)) for n, a in steps)
        self._wall_end = t0 + timeout
        self.meter.start()  # the match's costs count from here (modules loaded)
        self._next_memory_check = 256
        self._drain_logs()
        self._sample_poses()
        ready = [t for t in self.tags if self._queues.get(t)]
        try:
            while self.forfeit is None:
                for tag in ready:
                    with self.meter.serving(self.team_of[tag]):
                        self._serve(tag)
                    self._check_memory()
                    if self.forfeit is not None:
                        break
                if self.forfeit is not None or not self._motions or self.arena.time >= t_end - 1e-9:
                    break
                ready = self._advance(t_end)
        except _Ended:
            pass
        self._ending = self._ending or (self.forfeit.team if self.forfeit else None)
        self._finish("time is up" if self.forfeit is None else self.forfeit.message)
        return MatchRun(score=self.score(), sim_seconds=round(self.arena.time - start_time, 6),
                        wall_seconds=time.monotonic() - t0, events=self.events[first_event:],
                        finds=self.finds[first_find:], outcomes=self._outcomes, scores=self.scores())

    def log_text(self) -> str:
        """Everything the team code printed or logged, in order."""
        return "".join(line.text for line in self.logs)

    def score(self, team: str | None = None) -> float:
        """A team's score so far (victims found minus penalties; default: the first team's)."""
        return self.board.score_of(team or self.team)

    def scores(self) -> dict[str, float]:
        """Every playing team's score so far."""
        return {name: self.board.score_of(name) for name in self.teams}

    def true_cell(self, tag: int | None = None) -> tuple[int, int]:
        """Where the robot really is (the arena's ground truth, rounded to a cell)."""
        p = self.arena.pose(str(self.tags[0] if tag is None else tag))
        return int(round(p.x)), int(round(p.y))

    def write_events(self, path: str | os.PathLike[str]) -> Path:
        """Write the event log as JSON lines (sorted keys); returns the path."""
        p = Path(path)
        p.write_text("".join(_json_line(e) + "\n" for e in self.events), encoding="utf-8")
        return p

    def write_log(self, path: str | os.PathLike[str]) -> Path:
        """Write the match as a core event log (``robo_comp-eventlog``): what ``robo-comp
        replay`` plays and walls and consoles show. Only the core's topics go in; the times
        are simulated seconds, so identical runs give byte-identical files."""
        from robo_comp.protocol.logfile import write_log
        from robo_comp.world.public import arena_payload

        names = [t.name for t in self.scenario.teams] or list(self.teams)
        head: list[tuple[str, str | None, dict[str, Any], float]] = [("core.started", None, {"router": "bench", "teams": names,
                                        "arena": arena_payload(self.scenario, names)}, 0.0)]
        for tag in self.tags:
            x, y, h = self._start[tag]
            head.append(("robot.registered", self.team_of[tag],
                         {"tag": tag, "team": self.team_of[tag], "robot_id": f"{self.team_of[tag]}-{tag}",
                          "x": x, "y": y, "heading": h, "tasks": []}, 0.0))
        # an event's data keeps its ``team`` and ``t`` (a score line's match time, as the core logs it)
        body = [(e["topic"], e["team"], {k: v for k, v in e.items() if k != "topic"}, e["t"])
                for e in self.events if e["topic"] in TOPICS]
        return write_log(Path(path), head + body)

    def close(self) -> None:
        """Stop the sandbox processes."""
        for sb in self.sandboxes.values():
            sb.close()

    def __enter__(self) -> Bench:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ the step-locked loop
    def _event(self, topic: str, team: str | None, **data: Any) -> dict[str, Any]:
        ev = {"t": round(self.arena.time, 6), "topic": topic, "team": team, **data}
        self.events.append(ev)
        b = self.budget
        if team is not None and team in self.used and (b.events is not None or b.log_bytes is not None):
            used = self.used[team]
            used["events"] += 1
            used["log_bytes"] += len(_json_line(ev)) + 1
            self._check_memory()
            if b.events is not None and used["events"] > b.events:
                self._lose(team, "events", f"its robots caused more than {b.events} events in the match "
                                           "(calls, pictures, printed lines)")
            elif b.log_bytes is not None and used["log_bytes"] > b.log_bytes:
                self._lose(team, "log_bytes", f"its robots filled more than {b.log_bytes // 1024} KiB of the "
                                              "match's log (calls, pictures, printed lines)")
        return ev

    def _lose(self, team: str, limit: str, why: str) -> None:
        """``team`` went over a match limit: the match ends as its forfeit (the first one counts)."""
        if self.forfeit is None:
            self.forfeit = Forfeit(team, limit, f"team {team} forfeits the match: {why}", round(self.arena.time, 6))

    def _check_memory(self) -> None:
        """An entrant whose memory (:meth:`EntrantMeter.memory_mib`) is over
        :attr:`Budget.memory_mib` forfeits."""
        limit = self.budget.memory_mib
        if limit is None or self.forfeit is not None:
            return
        self._next_memory_check -= 1
        if self._next_memory_check > 0:
            return
        self._next_memory_check = 256
        for team in self.teams:
            mib = self.meter.memory_mib(team)
            if mib > limit:
                self._lose(team, "memory_mib", f"its robots took {mib:.1f} MiB of memory in the match (limit "
                                               f"{limit:g} MiB: its sandbox's growth and the worker's while serving them)")

    def _pay(self, tag: int, name: str) -> float:
        """Draw ``name``'s price from robot ``tag``'s call budget; returns the simulated time at
        which it is paid (now, or when the bucket has refilled)."""
        b = self.budget
        cost = b.picture_cost if name in PICTURE_CALLS else 1.0
        now = self.arena.time
        left, at = self._tokens.get(tag, (float(b.call_burst), now))
        if b.calls_per_second > 0:
            left = min(float(b.call_burst), left + (now - at) * b.calls_per_second)
        left -= cost
        when = now
        if left < 0:
            if b.calls_per_second <= 0:
                when = now + self.dt  # no rate: one clock step per call over the burst
                left = 0.0
            else:
                when = now + (-left) / b.calls_per_second
        self._tokens[tag] = (left, now) if when == now else (0.0, when)
        return when

    def _sample_poses(self) -> None:
        """Log every robot's true pose every ``pose_sample`` simulated seconds (as the core logs
        position samples), for replays and walls."""
        if self.pose_sample <= 0 or self.arena.time < self._next_sample - 1e-9:
            return
        poses = [self._true_pose(tag) for tag in self.tags]
        self._event("robot.positions", None, tags=list(self.tags), x=[p[0] for p in poses],
                    y=[p[1] for p in poses], heading=[p[2] for p in poses])
        self._next_sample = self.arena.time + self.pose_sample

    def _true_pose(self, tag: int) -> tuple[float, float, float]:
        p = self.arena.pose(str(tag))
        return round(float(p.x), 3), round(float(p.y), 3), round(float(p.heading), 1)

    def _serve(self, tag: int) -> None:
        """Let robot ``tag`` go on at the current simulated time until it waits for a movement or
        has nothing left to do: answer its finished movement or start its next task, then answer
        its calls as they come."""
        m = self._motions.get(tag)
        if m is not None and m.done and not self.arena.is_moving(str(tag)) and self.arena.time >= m.until - 1e-9:
            del self._motions[tag]
            if m.answer is not None:
                ok, value = m.answer
                if ok:
                    self._resolve(tag, m.call_id, m.name, m.args, value)
                else:
                    self._reject(tag, m.call_id, m.name, m.args, str(value))
            elif m.error is not None:
                self._reject(tag, m.call_id, m.name, m.args, m.error)
            else:
                self._resolve(tag, m.call_id, m.name, m.args, list(_BenchSite(self, tag).pose()))
        elif tag not in self._runs:
            self._start_next(tag)
        while tag in self._computing:
            self._handle_records(self.team_of[tag])

    def _handle_records(self, team: str) -> None:
        """Wait (a little) for what ``team``'s sandbox says and act on it."""
        from robo_comp.sandbox.parent import RpcCall

        t0 = time.monotonic()
        recs = self.sandboxes[team].poll(0.05)
        now = time.monotonic()
        used = self.used[team]  # every team of the bench has its counts from the start
        used["wall_seconds"] += now - t0
        cpu = used["cpu_seconds"] = self.meter.wait(team, now - t0)
        b = self.budget
        if b.cpu_seconds is not None and cpu > b.cpu_seconds:
            self._lose(team, "cpu_seconds", f"its code computed for more than {b.cpu_seconds:g} s of CPU time in "
                                            "the match")
        elif b.wall_seconds is not None and used["wall_seconds"] > b.wall_seconds:
            self._lose(team, "wall_seconds", f"the match waited more than {b.wall_seconds:g} s of real time for "
                                             "its code")
        if self._ending is not None:
            pass  # the match is ending: its runs are being cancelled
        elif self.forfeit is not None and team == self.forfeit.team:
            self._ending = team  # stop waiting for it: its runs are cancelled as the match ends
            raise _Ended()
        elif now > self._wall_end:
            if self.budget.wall_seconds is not None:  # a league match: the most computing entrant forfeits
                slow = max(self.teams, key=lambda t: (self.meter.read_cpu(t), -self.teams.index(t)))
                self._lose(slow, "wall_seconds", "the match ran out of real time, and its code computed the longest")
                self._ending = slow
                raise _Ended()
            raise AssertionError("the bench ran out of real time (run_match timeout): team code "
                                 f"of robots {sorted(self._computing)} did not answer")
        for rec in recs:
            if isinstance(rec, RpcCall):
                self._on_call(team, rec)
            else:
                self._on_record(team, rec)

    def _start_next(self, tag: int) -> None:
        q = self._queues.get(tag)
        team = self.team_of[tag]
        while q:
            name, args = q.popleft()
            task_id = self._next_task
            self._next_task += 1
            try:
                rid = self.sandboxes[team].start_task(tag, name, args)
            except RoboCompError as e:
                self._task_done(tag, task_id, name, {"ok": False, "state": "failed", "status": e.message,
                                                     "result": None, "start_error": True})
                continue
            self._runs[tag] = rid
            self._run_tag[(team, rid)] = tag
            self._task_of[tag] = (task_id, name, list(args))
            self._computing.add(tag)
            self._event("task.given", team, tag=tag, task_id=task_id, name=name, args=args, mode="queue",
                        by="bench")
            self._event("task.started", team, tag=tag, task_id=task_id, name=name, args=args)
            return

    def _task_done(self, tag: int, task_id: int, name: str, outcome: dict[str, Any]) -> None:
        ev = self._event("task.done", self.team_of[tag], tag=tag, task_id=task_id, name=name, **outcome)
        self._outcomes.setdefault(tag, []).append(ev)
        if self._on_done is not None:
            more = self._on_done(tag, ev)
            if more:  # what the team gives now runs before the robot's queue
                self._queues.setdefault(tag, deque()).extendleft((str(n), list(a)) for n, a in reversed(list(more)))
        self._start_next(tag)

    def _on_record(self, team: str, rec: Any) -> None:
        from robo_comp.sandbox.parent import LogLine, SandboxStopped, TaskDone, TaskFailed as SbFailed

        if isinstance(rec, LogLine):
            self.logs.append(rec)
            self._event("robot.log", team, tag=rec.tag, stream=rec.stream, text=rec.text)
        elif isinstance(rec, (TaskDone, SbFailed)):
            tag = self._run_tag.pop((team, rec.run_id), None)
            if tag is None or self._runs.get(tag) != rec.run_id:
                return
            del self._runs[tag]
            self._computing.discard(tag)
            self._motions.pop(tag, None)
            task_id, name, _ = self._task_of.pop(tag)
            why = self._ended.pop((team, rec.run_id), None)
            if isinstance(rec, TaskDone):
                out = ({"ok": True, "state": "done", "status": "done", "result": _plain_tree(rec.result)}
                       if why is None else {"ok": False, "state": "cancelled", "status": why, "result": None,
                                            "reason": "stopped", "line": None})
            else:
                out = {"ok": False, "state": "cancelled" if why else "failed", "status": why or rec.message,
                       "result": None, "reason": "stopped" if why else rec.reason, "line": None if why else rec.line}
            self._task_done(tag, task_id, name, out)
        elif isinstance(rec, SandboxStopped):
            self._event("sandbox.stopped", team, reason=rec.reason, message=rec.message)

    def _on_call(self, team: str, c: Any) -> None:
        sb = self.sandboxes[team]
        tag = self._run_tag.get((team, c.run_id))
        if tag is None or self._runs.get(tag) != c.run_id:
            sb.reject(c.call_id, "this robot is not running that task any more")
            return
        self.calls.append((tag, c.name, list(c.args)))
        site = _BenchSite(self, tag)
        args = list(c.args)
        if c.name in MOVEMENT_CALLS:
            self._computing.discard(tag)
            m = _Motion(c.call_id, c.name, args, host_answers.movement_steps(site, c.name, args))
            self._motions[tag] = m
            try:
                self._step(tag, m)
            except (TypeError, ValueError, IndexError) as e:
                m.done, m.error = True, host_answers.call_failed(c.name, args, e)
            return
        until = self._pay(tag, c.name)  # the call budget: answered now, or when it is paid
        held = until > self.arena.time + 1e-9
        if held:
            self.used[team]["held_calls"] = self.used[team].get("held_calls", 0.0) + 1

        def settle(ok: bool, value: Any) -> None:
            message = "" if ok else (value if isinstance(value, str) else str((value or {}).get("message", "refused")))
            if held:  # answered when the budget has paid for it, as a busy host answers later
                self._computing.discard(tag)
                m = _Motion(c.call_id, c.name, args, _no_steps(), answer=(ok, value if ok else message), until=until)
                self._motions[tag] = m
            elif ok:
                self._resolve(tag, c.call_id, c.name, args, value)
            else:
                self._reject(tag, c.call_id, c.name, args, message)

        try:
            value = host_answers.answer_call(site, c.name, args, settle)
        except (RoboCompError, host_answers.Refused) as e:
            settle(False, getattr(e, "message", None) or str(e))
            return
        except (TypeError, ValueError, IndexError) as e:
            settle(False, host_answers.call_failed(c.name, args, e))
            return
        if value is not PENDING:
            settle(True, value)

    def _resolve(self, tag: int, call_id: int, name: str, args: list[Any], value: Any) -> None:
        value = _plain_tree(value)
        team = self.team_of[tag]
        self._event("robot.call", team, tag=tag, name=name, args=list(args), ok=True, answer=value)
        self.sandboxes[team].resolve(call_id, value)
        self._computing.add(tag)

    def _reject(self, tag: int, call_id: int, name: str, args: list[Any], message: str) -> None:
        team = self.team_of[tag]
        self._event("robot.call", team, tag=tag, name=name, args=list(args), ok=False, error=message)
        self.sandboxes[team].reject(call_id, message)
        self._computing.add(tag)

    def _step(self, tag: int, m: _Motion) -> None:
        """Take a movement's next step: command the arena, or plan at once (the host plans in
        its planner thread; on the bench no time passes), or end the movement."""
        from robo_comp.world.planner import find_path

        sent: Any = None
        while True:
            try:
                step = m.steps.send(sent)
            except StopIteration:
                m.done = True
                return
            except host_answers.Refused as e:
                m.done, m.error = True, str(e)
                return
            sent = None
            if isinstance(step, Plan):
                sent = find_path(self.arena.walls, _BenchSite(self, tag).free_cell(), step.goal)
            elif isinstance(step, Turn):
                self.arena.command(str(tag), "turn", step.degrees)
                return
            elif isinstance(step, Move):
                self.arena.command(str(tag), "goto", (step.x, step.y))
                return

    def _advance(self, t_end: float) -> list[int]:
        """Step the arena until a movement ends (or the time is up); returns the robots to serve."""
        while self.arena.time < t_end - 1e-9:
            bumped: dict[int, dict[str, Any]] = {}
            for ev in self.arena.step(min(self.dt, t_end - self.arena.time)):
                tag = int(ev.tag)
                team = self.team_of.get(tag)
                if ev.kind == "bump":
                    other = ev.data.get("other")
                    self._event("robot.bump", team, tag=tag, x=ev.data["x"], y=ev.data["y"],
                                what=ev.data["what"], other=int(other) if other else None)
                    self._score({"kind": "robot.bump", "team": team, "tag": tag})
                    bumped[tag] = ev.data
                elif ev.kind == "zone":
                    self._event("robot.zone", team, tag=tag, kind=ev.data["kind"], x=ev.data["x"], y=ev.data["y"])
            self.loc.update()
            self._sample_poses()
            ready = []
            for tag in list(self._motions):
                if tag in bumped and tag in self._runs:
                    b = bumped[tag]
                    other = b.get("other")
                    self._stop_run(tag, host_answers.stop_status(b, f"robot {other}" if other else None))
                    ready.append(tag)
                    continue
                if self.arena.is_moving(str(tag)):
                    continue
                m = self._motions[tag]
                if not m.done:
                    self._step(tag, m)
                if not self.arena.is_moving(str(tag)) and m.done and self.arena.time >= m.until - 1e-9:
                    ready.append(tag)
            if ready:
                return sorted(ready, key=self.tags.index)
        return []

    def _stop_run(self, tag: int, why: str) -> None:
        """End robot ``tag``'s task as the host does (a bump, the end of the match): halt and
        cancel its run; the cancelled run's end is awaited so the next robot finds team code still."""
        self.arena.command(str(tag), "halt")
        self._motions.pop(tag, None)
        rid = self._runs.get(tag)
        if rid is None:
            return
        team = self.team_of[tag]
        self._ended[(team, rid)] = why
        self.sandboxes[team].cancel(rid)
        self._computing.add(tag)
        while tag in self._computing:
            self._handle_records(team)

    def _finish(self, why: str) -> None:
        """The time is up: cancel what still runs (in tag order), drop the queues."""
        self._on_done = None
        for q in self._queues.values():
            q.clear()
        for tag in [t for t in self.tags if t in self._runs]:
            self._stop_run(tag, why)
        self._next_sample = 0.0
        self._sample_poses()
        extra = {} if self.forfeit is None else {"forfeit": {"team": self.forfeit.team, "limit": self.forfeit.limit,
                                                             "message": self.forfeit.message}}
        self._event("match.phase", EVERYONE, phase="finished", elapsed=round(self.arena.time, 3),
                    duration=float(self.scenario.duration), action="end", by="bench", scores=self.scores(),
                    victims={name: sorted(self.board.found.get(name, set())) for name in self.teams}, **extra)

    def _drain_logs(self) -> None:
        from robo_comp.sandbox.parent import RpcCall

        for team, sb in self.sandboxes.items():
            for rec in sb.poll(0.0):
                if isinstance(rec, RpcCall):
                    self._on_call(team, rec)
                else:
                    self._on_record(team, rec)

    def _score(self, event: dict[str, Any]) -> None:
        for ln in self.board.apply(event, self.arena.time):
            self._event("score.change", ln.team, points=ln.points, kind=ln.kind, reason=ln.reason,
                        victim=ln.victim)

    # ------------------------------------------------------------------ pictures and finds
    def _picture(self, tag: int) -> dict[str, Any]:
        """A picture at the true pose, recorded by the judge (the victims in view count as
        examined, as in the core)."""
        p = self.arena.pose(str(tag))
        team = self.team_of[tag]
        rec = self.judge.picture(team, tag, float(p.x), float(p.y), float(p.heading))
        self._event("picture", team, id=rec["id"], tag=tag, x=rec["x"], y=rec["y"], heading=rec["heading"],
                    victims=list(rec["victims"]))
        return rec

    def _find(self, tag: int, body: dict[str, Any]) -> dict[str, Any]:
        team = self.team_of[tag]
        record, state = self.judge.find(team, tag, body["x"], body["y"], body["kind"], body["evidence"],
                                        round(self.arena.time, 6))
        verdict = record["verdict"]
        self.finds.append(dict(record, state=state))
        self._event("find.reported", team, id=record["id"], tag=tag, x=record["x"], y=record["y"],
                    kind=record["kind"], state=state, evidence=record["evidence"], message=verdict["reason"])
        self._score({"kind": "find.judged", "team": team, "tag": tag, "verdict": verdict})
        return {"id": record["id"], "state": state, "message": verdict["reason"]}


class _Ended(Exception):
    """Internal: the match ends now (an entrant's forfeit); unwinds the step-locked loop."""


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


__all__ = ["Bench", "Budget", "CALL_BURST", "Forfeit", "MatchRun", "PICTURE_CALLS", "MOVEMENT_CALLS", "POSE_SAMPLE", "TaskError", "TaskStep", "report_seen",
           "sweep_plan"]

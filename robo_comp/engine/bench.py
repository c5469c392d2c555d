"""The bench: a match played in one process on a seeded, step-locked simulated clock.

One engine for tests, benches and the league, and the same match as a live one: the bench is a
driver of the match model (:class:`robo_comp.match.model.Match`, which a live core drives too)
and of the task runtime (:class:`robo_comp.robots.runtime.TaskRuntime`, which a robot host runs
too). Its robots are the host's simulated robots (:class:`~robo_comp.robots.drivers.ArenaDriver`
in a seeded :class:`~robo_comp.world.arena.Arena`); their built-in tasks are the plugins' and
their team code runs in the real sandbox (:class:`~robo_comp.robots.teamcode.TeamCode`,
step-locked). :meth:`Bench.write_log` writes the match as a core event log, which ``robo-comp
replay``, the wall, the web page and the consoles show like any recorded match.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from robo_comp.engine.budget import CALL_BURST, PICTURE_CALLS, Budget, CallBuckets, Forfeit
from robo_comp.engine.usage import EntrantMeter
from robo_comp.engine.plans import TaskStep
from robo_comp.errors import BadTaskError, FieldError, RoboCompError, UnavailableError
from robo_comp.protocol.states import Phase
from robo_comp.protocol.topics import TOPICS
from robo_comp.robots import teamcode as host_answers
from robo_comp.robots.runtime import RunningTask, SimRobot, TaskRuntime, plan_around
from robo_comp.robots.steps import Compute, Plan, TaskSpec
from robo_comp.robots.teamcode import Reply, TeamCode
from robo_comp.sandbox.parent import LogLine, Sandbox
from robo_comp.world.scenario import DEFAULT_SCENARIO, resolve_scenario
from robo_comp.world.video import FPS, encode_webm

if TYPE_CHECKING:
    from robo_comp.sandbox.contract import ModuleInfo
    from robo_comp.sandbox.parent import Limits
    from robo_comp.world.scenario import Scenario

#: Robot calls that move the robot: they take simulated time and end at a movement's end.
MOVEMENT_CALLS = host_answers.MOVEMENT_CALLS
#: Seconds of simulated time between two logged samples of the robots' reported poses.
POSE_SAMPLE = 0.5
#: Seconds of simulated time between two reports of a moving robot's pose (a host's report rate).
REPORT_PERIOD = 0.1
#: Seconds between two reports of a robot standing still.
IDLE_REPORT = 1.0
#: The clock's step while every robot stands still and the match runs on (a match is not over
#: when its robots are idle; nothing moves, so a longer step changes nothing).
IDLE_STEP = 1.0
#: The engine's handle for the host of its robots (a live core knows a routing id there).
HOST = "engine"


class TaskError(AssertionError):
    """A team task failed on the bench (``message``, ``reason`` and ``line`` as the sandbox said)."""

    def __init__(self, message: str, reason: str, line: int | None) -> None:
        super().__init__(message)
        self.message = message
        self.reason = reason
        self.line = line


@dataclass
class MatchRun:
    """What :meth:`Bench.run_match` returns.

    ``events`` is this run's part of the bench's event log, ``finds`` the reports judged during
    the run, ``outcomes`` per robot tag the ``task.done`` events of its tasks in order (and a
    ``refused`` entry for a task the robot would not take), ``sim_seconds`` the simulated time
    the run took, ``score`` the first team's score at its end and ``scores`` every team's (every
    run so far counts), ``wall_seconds`` the real time it took.
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


class _Ended(Exception):
    """Internal: the match ends now (an entrant's forfeit); unwinds whatever the bench is doing."""


class TeamSide:
    """One team's side of an engine match: its robots, its sandboxed code, and what its code asks
    of the match. A robot host carries one team's robots and its
    :class:`~robo_comp.robots.teamcode.TeamCode`; on the engine a TeamSide plays that part for each
    team (it is the ``CodeHost`` of the team's code): pictures, finds and the radio go to the match
    in the same process, printed lines become ``robot.log`` events."""

    def __init__(self, bench: Bench, team: str, limits: Any) -> None:
        self.bench = bench
        self.team: str | None = team
        self.seed = bench.seed
        self.pm = bench.pm
        self.world = bench.arena
        self.walls = bench.walls
        #: What the team's planners avoid: the map's walls and the obstacles its robots reported.
        self.blocked = bench.walls.copy()
        self.foreign = None  # one arena: every robot of the match is in it already
        #: The team's robots by robot id (what its robots see of their host: the runtime's RobotWorld).
        self.robots: dict[str, SimRobot] = {}
        #: tag -> the team's robots (the CodeRobots its code acts for).
        self.by_tag: dict[int, SimRobot] = {}
        self.code = TeamCode(self, limits, step_locked=True, pacer=bench.pay, on_answer=bench.answered,
                             deterministic=True)

    @property
    def sandbox(self) -> Sandbox:
        """The team's sandbox process (started on first use)."""
        return self.code._sandbox()

    # ------------------------------------------------------------------ CodeHost
    def upload_answered(self, rid: int, results: list[dict[str, Any]]) -> None:
        """Loads on the engine wait for their answer (:meth:`TeamCode.load_now`): nothing to send."""

    def team_log(self, tag: int | None, stream: str, text: str) -> None:
        """A line the team's code printed: kept for :meth:`Bench.log_text` and logged."""
        self.bench.logs.append(LogLine(None, tag, stream, text))
        self.bench.emit("robot.log", self.team, {"tag": tag, "stream": stream[:16], "text": text[:2000]})

    def code_request(self, type_: str, body: dict[str, Any], on_reply: Reply) -> None:
        """A find or a radio message from team code, answered by the match at once."""
        bench = self.bench
        r = bench.match.registry.get(int(body["tag"]))
        try:
            if type_ == "find":
                record, state = bench.match.contest.find(r.team, r.tag, body["x"], body["y"], body.get("kind", ""),
                                                         body.get("evidence", []))
                bench.finds.append(dict(record, state=state))
                on_reply(True, {"id": record["id"], "state": state, "message": record["verdict"]["reason"]})
            elif type_ == "radio":
                on_reply(True, {"delivered": bench.match.radio(r, body.get("to"), body.get("data"))})
            elif type_ == "obstacle":
                on_reply(True, {"new": bench.reported(r, body.get("x"), body.get("y"))})
            else:
                raise UnavailableError(f"the engine does not serve {type_!r}")
        except RoboCompError as e:
            on_reply(False, {"message": e.message, "code": e.code})

    def code_picture(self, r: Any, on_reply: Reply) -> None:
        """A picture for team code, judged by the match as the core judges a host's picture."""
        pid, seen = self.bench.picture(r)
        on_reply(True, {"id": pid, "seen": seen})

    def team_draw(self, tags: list[int], frames: list[list[Any]]) -> None:
        """The robots' new frames of debug drawing, logged as ``debug.draw`` for the team (as a
        core logs a host's ``draw``); costs nothing: no match limit counts it."""
        bench = self.bench
        data = {"team": self.team, "tags": tags, "frames": frames}
        t = round(bench.arena.time, 6)
        bench.events.append({**data, "t": t, "topic": "debug.draw", "team": self.team})
        bench._records.append(("debug.draw", self.team, data, t))


class Bench:
    """Team modules in the real sandbox, robots simulated in-process from a scenario, on a
    simulated clock that only advances when every robot's team code waits for a movement.

    ``Bench(scenario, team, robots=1, seed=0)`` builds the simulated arena (seeded: the scenario's
    seed plus ``seed``), registers ``robots`` robots of ``team`` with the match in its start zone
    (tags from 101, as a core gives them) and their team's sandbox. ``teams={"red": 4, "blue": 4}``
    plays several teams instead (registered in that order). ``speed`` (cells per second) overrides
    the scenario's robot speed, as ``robo-comp robots --speed`` does. ``practice`` (default):
    the match runs from the start with no time limit, as ``core --practice``; ``practice=False``
    plays the scenario's match: it starts at once and finishes itself when its time is up.

    :meth:`run` runs one task on one robot and returns its result; :meth:`run_match` runs task
    lists on many robots for a simulated duration and returns a :class:`MatchRun` (scores,
    finds, an event log). Both use the same **step-locked** loop: team code runs one robot at a
    time, and the simulated clock advances (steps of ``dt`` seconds) only when every robot waits
    for a movement; calls that take no time are answered at the current simulated time, paid from
    the robot's call budget (:class:`~robo_comp.engine.budget.Budget`). Nothing depends on real
    time, so the same scenario, seed and code give the same event log.

    The bench is a team too: it gives each robot the next task of its list when the robot is
    idle, as a console does (``give``), and the match decides the rest: task ids and outcomes,
    the bump rule (a bump ends the task and costs the collision penalty), judging and scoring
    (the installed scoring rules, or ``pm``'s), the phases. Team code's ``radio`` reaches its
    teammates through the match, as live.
    """

    def __init__(self, scenario: str | os.PathLike[str] | Scenario | None = DEFAULT_SCENARIO,
                 team: str | None = None, *, robots: int = 1, seed: int = 0,
                 limits: Limits | None = None, dt: float = 0.05, max_sim_seconds: float = 600.0,
                 speed: float | None = None, teams: Mapping[str, int] | None = None,
                 pose_sample: float = POSE_SAMPLE, budget: Budget | None = None, practice: bool = True,
                 pm: Any = None) -> None:
        from robo_comp.match.model import Match
        from robo_comp.plugins.manager import get_plugin_manager
        from robo_comp.robots.drivers import ArenaDriver
        from robo_comp.robots.host import collect_tasks
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
        self.arena = Arena(sc, seed=sc.seed + seed, capacity=max(16, sum(playing.values())))
        if speed:
            self.arena.speed = float(speed)
        self.loc = Localization(self.arena)
        self.walls = sc.walls  # the map's (the arena's debris is for the robots' sensors to find)
        self.dt = dt
        self.max_sim_seconds = max_sim_seconds
        self.pose_sample = pose_sample
        self.pm = pm or get_plugin_manager()
        self.budget = budget or Budget()
        self.buckets = CallBuckets(self.budget, dt)
        #: The event log of every run so far: dicts with ``t``, ``topic``, ``team`` and the event's data.
        self.events: list[dict[str, Any]] = []
        self._records: list[tuple[str, str | None, dict[str, Any], float]] = []  # the core log's records
        self.debug_replay = "team"  # who sees team code's debug drawing in a replay (protocol.topics.DEBUG_REPLAY)
        self.finds: list[dict[str, Any]] = []
        self.calls: list[tuple[int, str, list[Any]]] = []
        self.logs: list[LogLine] = []
        #: Per team: events its robots caused, their bytes as JSON lines, real seconds the match
        #: waited for its code and the CPU seconds its code used.
        self.used: dict[str, dict[str, float]] = {t: {"events": 0.0, "log_bytes": 0.0, "wall_seconds": 0.0,
                                                      "cpu_seconds": 0.0} for t in self.teams}
        #: Set when an entrant went over a match limit; the match then ends (see :class:`Budget`).
        self.forfeit: Forfeit | None = None
        self._directives: deque[tuple[SimRobot, str, dict[str, Any]]] = deque()
        #: Robots whose host failed (:meth:`lose`): they hold still, report nothing, get nothing.
        self.down: set[int] = set()
        #: The videos filmed (WebM bytes by id; the match has their records).
        self.videos: dict[int, bytes] = {}
        self._plans: dict[int, deque[TaskStep]] = {}
        self._outcomes: dict[int, list[dict[str, Any]]] = {}
        self._on_done: Callable[[int, dict[str, Any]], Iterable[TaskStep] | None] | None = None
        self._wall_end = math.inf
        #: CPU, real time and memory per entrant, for the match limits (robo_comp/engine/usage.py).
        self.meter = EntrantMeter(self.teams, lambda team: self.sides[team].code.sb)
        self._next_memory_check = 256
        self._next_sample = 0.0
        self._next_report = 0.0
        self.holding = False
        max_speed = None
        if speed:
            fastest = max([1.0, *(z.speed_factor for z in sc.zones)])
            max_speed = float(speed) * fastest * 4.0
        self.match = Match(sc, names, self, self.pm, practice=practice, robots_per_team=max(playing.values()),
                           max_speed=max_speed, wall=self._now, mono=self._now)
        self.config = self.match.config
        self.runtime = TaskRuntime(self)
        self.builtin: dict[str, TaskSpec] = collect_tasks(self.pm)
        self.sides = {name: TeamSide(self, name, limits) for name in self.teams}
        self.robots: dict[str, SimRobot] = {}  # robot id -> robot (each team's side is its robots' world)
        team_of_robot: dict[str, str] = {}
        self.by_tag: dict[int, SimRobot] = {}
        self.tags_of: dict[str, list[int]] = {}
        self.team_of: dict[int, str] = {}
        for name, count in playing.items():
            cells = self.arena.free_start_cells(name)
            if len(cells) < count:
                raise FieldError(f"team {name}'s start zone has room for {len(cells)} robots, not {count}")
            for i, (x, y) in zip(range(count), cells):
                rid = f"{name}-{i + 1}"
                self.arena.add_robot(rid, name, x, y, 0.0)
                r = SimRobot(rid, ArenaDriver(self.arena, rid, self.loc), self.sides[name])
                self.robots[rid] = r
                self.sides[name].robots[rid] = r
                team_of_robot[rid] = name
        self.loc.update()
        for rid, r in self.robots.items():
            name = team_of_robot[rid]
            x, y, h = r.driver.pose
            reply = self.match.register(name, rid, HOST, {"robot_id": rid, "x": x, "y": y, "heading": h,
                                                          "speed": float(self.arena.speed), "tasks": self._adverts(r)})
            r.tag = reply["tag"]
            self.by_tag[r.tag] = r
            self.sides[name].by_tag[r.tag] = r
            self.tags_of.setdefault(name, []).append(r.tag)
            self.team_of[r.tag] = name
        self.tags = [t for name in self.teams for t in self.tags_of[name]]
        if not practice:
            self.match.contest.change("start", "bench")

    # ------------------------------------------------------------------ what the match holds
    @property
    def board(self) -> Any:
        """The match's scoreboard."""
        return self.match.contest.board

    @property
    def judge(self) -> Any:
        """The match's find judge (pictures and finds)."""
        return self.match.contest.judge

    @property
    def pictures(self) -> dict[int, dict[str, Any]]:
        """Every picture taken (the judge's records: ``id``, ``tag``, ``team``, pose, ``victims``)."""
        return self.judge.pictures

    @property
    def examined(self) -> dict[str, set[int]]:
        """The first team's examined victims: victim id -> the ids of pictures showing it."""
        return self.judge.examined.setdefault(self.team, {})

    @property
    def sandboxes(self) -> dict[str, Sandbox]:
        """Each team's sandbox process."""
        return {name: side.sandbox for name, side in self.sides.items()}

    @property
    def sandbox(self) -> Sandbox:
        """The first team's sandbox process."""
        return self.sides[self.team].sandbox

    def _now(self) -> float:
        return self.arena.time

    # ------------------------------------------------------------------ modules and tasks
    def load(self, path: str | os.PathLike[str], source: str | None = None, *, team: str | None = None) -> ModuleInfo:
        """Load a team module (a file, or ``source`` under the file name ``path``) into ``team``'s
        sandbox (default: the first team) for all its robots, through the checked contract, as an
        upload does; raises :class:`~robo_comp.errors.UploadError` when it is refused."""
        p = Path(path)
        text = p.read_text(encoding="utf-8") if source is None else source
        side = self.sides[team or self.team]
        module = side.code.load_now(p.name, text, list(side.by_tag))
        for r in side.by_tag.values():  # what the robots advertise now (the host's tasks_changed)
            self.match.advertise(self.match.registry.get(r.tag), self._adverts(r))
        return module

    def tasks(self, team: str | None = None) -> dict[str, dict[str, Any]]:
        """The tasks the loaded modules of ``team`` (default: the first) advertise."""
        return self.sides[team or self.team].sandbox.advertised_tasks()

    def _adverts(self, r: SimRobot) -> list[dict[str, Any]]:
        tasks = {name: t.advert() for name, t in self.builtin.items()}
        if r.tag:
            tasks.update(self.sides[self.team_of[r.tag]].code.adverts(r.tag))
        return list(tasks.values())

    def run(self, task: str, *args: Any, tag: int | None = None, timeout: float = 60.0) -> Any:
        """Run ``task(robot, *args)`` on robot ``tag`` (the first robot by default) until it ends
        (at most ``max_sim_seconds`` simulated seconds); return its result. Raises
        :class:`TaskError` if the task failed, :class:`~robo_comp.errors.BadTaskError` if the robot
        would not take it, and AssertionError if it did not end."""
        tag = self.tags[0] if tag is None else tag
        out = self.run_match({tag: [(task, list(args))]}, seconds=self.max_sim_seconds, timeout=timeout)
        done = out.outcomes.get(tag, [])
        if not done:
            raise AssertionError(f"task {task} did not finish within {self.max_sim_seconds:g} simulated s")
        d = done[-1]
        if d["ok"]:
            return d["result"]
        if d.get("refused"):
            raise BadTaskError(d["status"])
        why: dict[str, Any] = d["result"] if isinstance(d.get("result"), dict) else {}
        raise TaskError(d["status"], why.get("reason", "error"), why.get("line"))

    def run_match(self, plan: Mapping[int, Iterable[TaskStep]] | TaskStep, *, seconds: float | None = None,
                  on_done: Callable[[int, dict[str, Any]], Iterable[TaskStep] | None] | None = None,
                  timeout: float = 120.0) -> MatchRun:
        """Run tasks on the robots for ``seconds`` of simulated time (default: the scenario's
        ``duration``), or until every robot is idle (or the match is over); return a :class:`MatchRun`.

        ``plan`` maps a robot tag to the tasks it runs one after the other, ``[(name, args), ...]``;
        a single ``(name, args)`` runs on every robot. ``on_done(tag, outcome)`` is called when a
        task of ``tag`` ends (``outcome`` is its ``task.done`` event: ``ok``, ``status``,
        ``result``); the tasks it returns run next on that robot (before the rest of its list) --
        use it for what a team does between tasks (it must be deterministic for the run to be).
        ``timeout`` bounds the *real* time the run may take (a safety net). The run continues the
        bench's clock, score and log: call it again to go on (a task still running goes on too).
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
            self._plans.setdefault(tag, deque()).extend((str(n), list(a)) for n, a in steps)
        self._wall_end = t0 + timeout
        self.meter.start()  # the match's costs count from here (modules loaded)
        self._next_memory_check = 256
        try:
            self._sample()
            self._give_next()
            clock = self.match.contest.clock
            while self.forfeit is None and not self.holding and self.arena.time < t_end - 1e-9:
                step = self.dt
                if self._idle():
                    if math.isinf(clock.duration):  # practice: no match to wait for, the run is over
                        break
                    step = IDLE_STEP  # every robot stands still: the clock runs on to the match's end
                left = clock.remaining(self.arena.time)
                self._step(min(step, t_end - self.arena.time, left if left > 1e-9 else step))
        except _Ended:
            pass
        if self.forfeit is not None:
            self._end()
        self.match.contest.flush_score()
        self._on_done = None
        return MatchRun(score=self.score(), sim_seconds=round(self.arena.time - start_time, 6),
                        wall_seconds=time.monotonic() - t0, events=self.events[first_event:],
                        finds=self.finds[first_find:], outcomes=self._outcomes, scores=self.scores())

    def lose(self, tag: int, why: str = "its host stopped") -> None:
        """Robot ``tag``'s host fails (as a host killed mid-task): the robot stops where it is and
        says nothing more, and the match declares it lost, as a core does after three silent
        heartbeats (its work is offered to its team: :mod:`robo_comp.match.teamwork`)."""
        r = self.by_tag[tag]
        self.runtime.halt(r)
        self.down.add(tag)
        self.match.lost(self.match.registry.get(tag), why)
        self._carry_out()

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
        r = self.by_tag[self.tags[0] if tag is None else tag]
        p = self.arena.pose(r.robot_id)
        return int(round(p.x)), int(round(p.y))

    def write_events(self, path: str | os.PathLike[str]) -> Path:
        """Write the event log as JSON lines (sorted keys); returns the path."""
        p = Path(path)
        p.write_text("".join(_json_line(e) + "\n" for e in self.events), encoding="utf-8")
        return p

    def write_log(self, path: str | os.PathLike[str]) -> Path:
        """Write the match as a core event log (``robo_comp-eventlog``): what ``robo-comp
        replay`` plays and walls and consoles show. The records are the match's own, as a core
        logs them; the times are simulated seconds, so identical runs give byte-identical files."""
        from robo_comp.protocol.logfile import write_log
        from robo_comp.world.public import arena_payload

        names = [t.name for t in self.scenario.teams] or list(self.teams)
        head: list[tuple[str, str | None, dict[str, Any], float]] = [
            ("core.started", None, {"router": "bench", "teams": names, "arena": arena_payload(self.scenario, names),
                                    "debug_replay": self.debug_replay},
             0.0)]
        return write_log(Path(path), head + self._records)

    def close(self) -> None:
        """Stop the sandbox processes."""
        for side in self.sides.values():
            side.code.close()

    def __enter__(self) -> Bench:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ the match's output (MatchOutput)
    def emit(self, topic: str, team: str | None, data: dict[str, Any], *, log_it: bool = True) -> None:
        """An event of the match (or of the bench): into the bench's log at the simulated time."""
        if not log_it:
            return
        t = round(self.arena.time, 6)
        ev = {**data, "t": t, "topic": topic, "team": team}
        self.events.append(ev)
        if topic in TOPICS:
            self._records.append((topic, team, data, t))
        if topic != "robot.positions":
            self.pm.hook.robo_comp_event(topic=topic, team=team, data=data)
        if topic == "task.done":
            self._task_done(ev)
        self._charge(team, ev)

    def to_host(self, rec: Any, type_: str, body: dict[str, Any]) -> None:
        """A directive to robot ``rec``: carried out by the bench's loop, in order (a robot whose
        host failed gets nothing)."""
        r = self.by_tag.get(rec.tag)
        if r is not None and rec.tag not in self.down:
            self._directives.append((r, type_, body))

    def to_hosts(self, type_: str, body: dict[str, Any]) -> None:
        """``hold``: the match paused or finished; the robots hold still."""
        if type_ == "hold":
            self.holding = bool(body.get("on"))

    def finished(self) -> None:
        """The match finished (time up, or a forfeit): the robots hold; nothing to write here."""
        self.holding = True

    def discovered(self, r: Any, find: dict[str, Any]) -> None:
        """The engine keeps no map service (team code reads the walls)."""

    # ------------------------------------------------------------------ the runtime's env (RuntimeEnv)
    def spec(self, r: SimRobot, name: str) -> TaskSpec | None:
        """Task ``name`` as robot ``r`` runs it: its team's code first, else a built-in task."""
        side = self.sides[self.team_of[r.tag]]
        return side.code.task_spec(r.tag, name) or self.builtin.get(name)

    def plan(self, r: SimRobot, step: Plan) -> Any:
        """A path at once (no simulated time passes while the engine plans), on the team's map."""
        occupied = r.others_cells() if step.avoid_robots else set()
        return plan_around(self.sides[self.team_of[r.tag]].blocked, r.free_cell(), step.goal, occupied)

    def obstacle(self, r: SimRobot, cell: tuple[int, int]) -> None:
        """A cell robot ``r``'s sensors saw blocked: the match keeps it for the team's map (the
        robot's own map has it even if the match refused it, as a host marks it before it asks)."""
        rec = self.match.registry.get(r.tag)
        try:
            self.reported(rec, *cell)
        except RoboCompError:
            self.sides[rec.team].blocked[cell[1], cell[0]] = True

    def reported(self, rec: Any, x: Any, y: Any) -> bool:
        """Robot ``rec`` reports an obstacle (its sensors, or its team code): taken by the match (a
        refusal raises), then on its team's map at once (the engine is the team's one host)."""
        new = self.match.obstacle(rec, x, y)
        self.sides[rec.team].blocked[y, x] = True
        return new

    def capture(self, r: SimRobot, t: RunningTask, label: str) -> None:
        """A picture for a built-in task's evidence."""
        pid, _ = self.picture(r, label)
        t.pictures.append(pid)

    def frame(self, r: SimRobot) -> Any:
        """A frame of ``r``'s camera at its true pose."""
        return self.arena.camera_image(r.robot_id)

    def video(self, r: SimRobot, t: RunningTask, frames: list[Any], label: str) -> None:
        """The video written at once (no simulated time passes), kept in :attr:`videos`, recorded by
        the match where it tracks the robot (as the core records a host's video)."""
        data = encode_webm(frames)
        x, y, h = r.driver.truth()
        rec = self.match.video(self.match.registry.get(r.tag), {"x": float(x), "y": float(y), "heading": float(h)},
                               seconds=round(len(frames) / FPS, 3), frames=len(frames), label=label,
                               sha256=hashlib.sha256(data).hexdigest()[:16])
        self.videos[rec["id"]] = data
        t.videos.append(rec["id"])

    def compute(self, r: SimRobot, step: Compute) -> bool:
        """Wait for robot ``r``'s team code, with the simulated clock stopped (step-locked)."""
        team = self.team_of[r.tag]
        side = self.sides[team]
        t0 = time.monotonic()
        deadline = min(self._wall_end, t0 + 3600.0)
        answered = side.code.wait_run(step.run_id, deadline)
        used = self.used[team]
        waited = time.monotonic() - t0
        used["wall_seconds"] += waited
        cpu = used["cpu_seconds"] = self.meter.wait(team, waited)
        b = self.budget
        if b.cpu_seconds is not None and cpu > b.cpu_seconds:
            self._lose(team, "cpu_seconds", f"its code computed for more than {b.cpu_seconds:g} s of CPU time in the match")
        elif b.wall_seconds is not None and used["wall_seconds"] > b.wall_seconds:
            self._lose(team, "wall_seconds", f"the match waited more than {b.wall_seconds:g} s of real time for its code")
        if self.forfeit is not None:
            raise _Ended()
        if not answered:
            if self.budget.wall_seconds is not None:  # a league match: the most computing entrant forfeits
                slow = max(self.teams, key=lambda t: (self.meter.read_cpu(t), -self.teams.index(t)))
                self._lose(slow, "wall_seconds", "the match ran out of real time, and its code computed the longest")
                raise _Ended()
            raise AssertionError("the bench ran out of real time (run_match timeout): team code "
                                 f"of robot {r.tag} did not answer")
        return True

    def task_ended(self, r: SimRobot, task_id: int, ok: bool, status: str, result: Any) -> None:
        """Tell the match (the host's ``task.done``)."""
        rec = self.match.registry.get(r.tag)
        if rec.current is not None and rec.current.id == task_id:
            self.match.task_done(rec, {"task_id": task_id, "ok": ok, "status": status,
                                       "result": _plain_tree(result)})

    def interrupted(self, r: SimRobot, t: RunningTask, by_task_id: int) -> None:
        """The plugins hear of an interrupt before it takes effect."""
        self.pm.hook.robo_comp_task_interrupted(robot=r, task_name=t.name, task_id=t.id, by_task_id=by_task_id)

    # ------------------------------------------------------------------ team code's calls (TeamCode's hooks)
    def pay(self, tag: int, name: str) -> float:
        """The simulated seconds call ``name`` of robot ``tag`` waits for its call budget."""
        wait = self.buckets.pay(tag, name, self.arena.time)
        if wait > 0:
            used = self.used[self.team_of[tag]]
            used["held_calls"] = used.get("held_calls", 0.0) + 1
        return wait

    def answered(self, tag: int, name: str, args: list[Any], ok: bool, value: Any) -> None:
        """Every call team code made, as answered (``robot.call``, the bench's own event)."""
        self.calls.append((tag, name, list(args)))
        team = self.team_of.get(tag)
        if ok:
            self.emit("robot.call", team, {"tag": tag, "name": name, "args": list(args), "ok": True,
                                           "answer": _plain_tree(value)})
        else:
            self.emit("robot.call", team, {"tag": tag, "name": name, "args": list(args), "ok": False,
                                           "error": str(value)})

    def picture(self, r: SimRobot, label: str = "team code") -> tuple[int, list[dict[str, Any]]]:
        """A picture with robot ``r``'s camera at its true pose, judged where the match tracks the
        robot (as the core judges a host's picture); returns its id and what it shows."""
        rec = self.match.registry.get(r.tag)
        x, y, h = r.driver.truth()
        jx, jy, jh = self.match.judged_pose(rec, {"x": float(x), "y": float(y), "heading": float(h)}, "picture")
        meta = self.match.contest.picture(rec.team, rec.tag, jx, jy, jh, label=label[:64])
        return meta["id"], self.judge.describe(meta["victims"])

    # ------------------------------------------------------------------ the loop
    def _step(self, dt: float) -> None:
        """One step of the simulated clock: the arena moves, bumps are judged, poses reported,
        finished movements answered, the match's directives carried out."""
        for ev in self.arena.step(dt):
            r = self.robots.get(ev.tag)
            if r is None:
                continue
            if ev.kind == "bump":
                r.driver.bump = ev.data
                other = self.robots.get(ev.data.get("other") or "")
                rec = self.match.registry.get(r.tag)
                x, y, _ = self.match.judged_pose(rec, {"x": ev.data["x"], "y": ev.data["y"]}, "bump")
                self.match.contest.bump(rec.team, rec.tag, x, y, other.tag if other else None)
            elif ev.kind == "zone":
                self.emit("robot.zone", self.team_of[r.tag], {"tag": r.tag, "kind": ev.data["kind"],
                                                               "x": ev.data["x"], "y": ev.data["y"]})
        self.loc.update()
        self._report()
        if self.runtime.filming:
            self.runtime.film(dt)
        for tag in self.tags:
            r = self.by_tag[tag]
            if r.driver.step is not None and r.driver.update(dt):
                with self.meter.serving(self.team_of[tag]):  # what serving a robot grows is its team's
                    self.runtime.boundary(r)
                self._carry_out()
        self.match.contest.tick()
        self._sample()
        self._check_memory()
        self._give_next()
        self.match.contest.flush_score()  # the scoreboard once a step it changed in, as a core's once a turn

    def _carry_out(self) -> None:
        """Carry out the match's directives, in order (each may cause more)."""
        while self._directives:
            r, type_, body = self._directives.popleft()
            if type_ == "task.start":
                if r.task is None or r.task.id != body["task_id"]:
                    if r.task is not None:
                        r.driver.halt()
                    with self.meter.serving(self.team_of.get(r.tag)):
                        self.runtime.start(r, body)
            elif type_ == "task.interrupt":
                with self.meter.serving(self.team_of.get(r.tag)):
                    self.runtime.interrupt(r, body)
            elif type_ == "stop":
                self.runtime.halt(r)
            elif type_ == "radio":
                r.inbox.append({"from": body.get("from"), "data": body.get("data")})

    def _give_next(self) -> None:
        """Each idle robot with tasks left in its list gets the next one (as a console gives it)."""
        self._carry_out()
        for tag in self.tags:
            q = self._plans.get(tag)
            rec = self.match.registry.get(tag)
            while q and rec.current is None and not self.holding and tag not in self.down:
                name, args = q.popleft()
                try:
                    self.match.give(rec, name, list(args), queue=False, by="bench")
                except RoboCompError as e:  # the robot would not take it: the next one
                    self._outcome(tag, {"tag": tag, "name": name, "ok": False, "refused": True,
                                        "code": e.code, "status": e.message, "result": None})
                self._carry_out()

    def _idle(self) -> bool:
        """Nothing left to do: no robot runs a task, plans one or has one in its list."""
        return (not self._directives and not self.runtime.planning and all(
            self.match.registry.get(t).current is None and not self._plans.get(t) for t in self.tags
            if t not in self.down))

    def _task_done(self, ev: dict[str, Any]) -> None:
        tag = ev["tag"]
        self._outcome(tag, ev)
        if self._on_done is not None:
            more = self._on_done(tag, ev)
            if more:  # what the team gives now runs before the rest of the robot's list
                self._plans.setdefault(tag, deque()).extendleft((str(n), list(a)) for n, a in reversed(list(more)))

    def _outcome(self, tag: int, ev: dict[str, Any]) -> None:
        self._outcomes.setdefault(tag, []).append(ev)
        if ev.get("refused") and self._on_done is not None:
            more = self._on_done(tag, ev)
            if more:
                self._plans.setdefault(tag, deque()).extendleft((str(n), list(a)) for n, a in reversed(list(more)))

    def _report(self) -> None:
        """Report the robots' believed poses to the match, as a host does (moving robots every
        :data:`REPORT_PERIOD`, the others every :data:`IDLE_REPORT`)."""
        now = self.arena.time
        if now < self._next_report - 1e-9:
            return
        self._next_report = now + REPORT_PERIOD
        for name in self.teams:
            rows = [self.by_tag[t] for t in self.tags_of[name] if t not in self.down]
            due = [r for r in rows if r.driver.moving or now - r.last_report >= IDLE_REPORT - 1e-9]
            if not due:
                continue
            poses = [r.driver.pose for r in due]
            for r in due:
                r.last_report = now
            self.match.take_rows(HOST, name, [r.tag for r in due], [round(p[0], 3) for p in poses],
                                 [round(p[1], 3) for p in poses], [round(p[2], 1) for p in poses],
                                 [r.driver.moving for r in due], [None] * len(due),
                                 [round(self.loc.sigma(r.robot_id), 3) for r in due])

    def _sample(self) -> None:
        """Log the poses of the robots that moved, every ``pose_sample`` simulated seconds (as the
        core logs its position samples), for replays and walls."""
        if self.pose_sample <= 0 or self.arena.time < self._next_sample - 1e-9:
            return
        self._next_sample = self.arena.time + self.pose_sample
        self.match.tell_integrity()
        moved = self.match.moved
        if moved:
            tags = sorted(moved)
            moved.clear()
            self.emit("robot.positions", None, self.match.position_sample(tags))
        for side in self.sides.values():
            side.code.flush_drawing()  # team code's debug drawing, at the same ticks
        self.match.posed.clear()  # no live feed to conflate for

    def _end(self) -> None:
        """An entrant forfeited: the match finishes now, saying who and why."""
        f = self.forfeit
        assert f is not None
        for r in self.robots.values():
            self.runtime.halt(r)
        c = self.match.contest
        if c.phase is Phase.FINISHED:
            return
        if c.phase is Phase.SETUP:
            c.change("start", "bench")
        c.change("finish", "bench", forfeit={"team": f.team, "limit": f.limit, "message": f.message})

    # ------------------------------------------------------------------ limits
    def _charge(self, team: str | None, ev: dict[str, Any]) -> None:
        b = self.budget
        if team is None or team not in self.used or (b.events is None and b.log_bytes is None):
            return
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


__all__ = ["Bench", "Budget", "CALL_BURST", "Forfeit", "MatchRun", "MOVEMENT_CALLS", "PICTURE_CALLS", "POSE_SAMPLE",
           "TaskError", "TeamSide"]

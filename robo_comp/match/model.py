"""The match: one object that takes commands and says what follows, with no sockets.

:class:`Match` holds what is true in a match: its robots (:class:`~robo_comp.match.registry.Registry`)
with their statuses (:class:`~robo_comp.match.lifecycle.Lifecycle`, their one writer), their tasks
(:class:`~robo_comp.match.tasks.TaskMachine`), the poses it believes
(:class:`~robo_comp.match.plausibility.PoseGate`), and the contest (phases, clock, judging, scores:
:class:`~robo_comp.match.contest.Contest`). Two drivers run it the same way:

* the core (:class:`robo_comp.core.server.Core`), which proves who sends each command and routes
  the match's events and directives over ZeroMQ;
* the engine (:class:`robo_comp.engine.bench.Bench`), which runs robots and team code in one
  process on a simulated clock for tests, benches and league matches.

So a task gets the same id, the same states and outcome, a bump the same penalty, a find the
same verdict, wherever the match is played. Checks of *who* may command a robot are the core's;
checks of *what* a command may do (the phase, a disqualified robot, the advertised tasks, a pose
the robot could not have reached) are the match's.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import Any

from robo_comp.errors import (
    FieldError, ForbiddenError, ImplausibleError, NotYoursError, RateLimitError, TooLargeError, UnavailableError,
)
from robo_comp.match.contest import Contest
from robo_comp.match.lifecycle import Lifecycle
from robo_comp.match.output import MatchOutput
from robo_comp.match.plausibility import MAX_NOISE, MAX_SIGMA, PoseGate
from robo_comp.match.registry import Registry, RobotRecord
from robo_comp.match.tasks import TaskMachine, TaskRecord
from robo_comp.match.teamwork import TeamWork
from robo_comp.match.videos import Videos
from robo_comp.protocol import wire
from robo_comp.protocol.messages import MAX_RADIO, RADIO_RATE
from robo_comp.protocol.states import RobotStatus, TaskMode, TaskState
from robo_comp.protocol.taskspec import check_args, check_specs, find_spec
from robo_comp.scoring.config import ScoringConfig
from robo_comp.world.scenario import Scenario

#: The largest task result a host may report, once packed.
MAX_RESULT = 64 * 1024
#: Without ``max_speed``: the fastest a robot may be (cells/s) is this many times the scenario's
#: robot speed (hosts declare their robots' speed at ``register``; a faster claim is cut to this).
MAX_SPEED_FACTOR = 4.0


class Match:
    """One match (see the module docstring).

    ``out`` receives the events and directives; ``pm`` is the plugin manager whose scoring rules
    judge; ``wall`` stamps records (wall-clock seconds live, simulated seconds on the engine) and
    ``mono`` runs the match clock and the pose gate (monotonic seconds live, simulated on the
    engine). ``robots_per_team`` bounds registrations (None: the scenario's count per team);
    ``max_speed`` bounds declared speeds (None: :data:`MAX_SPEED_FACTOR` × the scenario's)."""

    def __init__(self, scenario: Scenario, teams: list[str], out: MatchOutput, pm: Any, *,
                 scoring: ScoringConfig | None = None, practice: bool = False,
                 robots_per_team: int | None = None, max_speed: float | None = None,
                 wall: Callable[[], float] = time.time, mono: Callable[[], float] = time.monotonic) -> None:
        self.scenario = scenario
        self.teams = list(teams)
        self.out = out
        self.pm = pm
        self.wall = wall
        self.mono = mono
        self.config = scoring or ScoringConfig.from_table(scenario.scoring)
        self.registry = Registry()
        self.contest = Contest(out, scenario, self.teams, pm, self.config, practice, mono, wall)
        self.lifecycle = Lifecycle(out, self.contest.feed, self.contest.disqualified_robots.__contains__)
        self.tasks = TaskMachine(self._task_started, self._task_finished, now=wall)
        self.next_task_id = 1
        #: A lost robot's work offered and moved to teammates; the obstacles each team reported.
        self.teamwork = TeamWork(self.registry, self.tasks, out, pm, self._give_moved,
                                 self.contest.disqualified_robots.__contains__)
        #: The videos robots filmed (examineArea's turn on the spot).
        self.videos = Videos(out, wall)
        self.robots_per_team = robots_per_team
        fastest_zone = max([1.0, *(z.speed_factor for z in scenario.zones)])
        #: The fastest a robot may drive (cells/s): a host's declared speed is cut to it.
        self.max_speed = float(max_speed) if max_speed else scenario.kinematics.speed * fastest_zone * MAX_SPEED_FACTOR
        self.default_speed = min(self.max_speed, scenario.kinematics.speed * fastest_zone)
        #: Fair play: which reported poses a robot could have reached (robo_comp.match.plausibility).
        self.gate = PoseGate(scenario.walls, self.max_speed)
        # claims about the world not believed since the last look: (tag, kind) -> [count, the last reason]
        self._implausible: dict[tuple[int, str], list[Any]] = {}
        #: Robots whose pose changed since the last position sample (the log's record).
        self.moved: set[int] = set()
        #: team -> robots that reported since the last position batch (the live feed's conflation).
        self.posed: dict[str, set[int]] = {}

    # ------------------------------------------------------------------ robots
    def robot_limit(self, team: str) -> int:
        """How many robots ``team`` may register: ``robots_per_team``, else what the scenario gives
        it (a team the scenario does not name: as many as its largest team)."""
        if self.robots_per_team is not None:
            return self.robots_per_team
        counts = {t.name: t.robots for t in self.scenario.teams}
        return counts.get(team, max(counts.values(), default=1))

    def admit(self, team: str, robot_id: str, b: dict[str, Any]) -> RobotRecord | None:
        """Whether robot ``robot_id`` of ``team`` may register with the body of its ``register``
        message ``b``: the robot it was (it comes back with the same tag), or None for a new one that
        the scenario has room for and that starts on a free cell; refused with a sentence otherwise
        (nothing is changed by a refusal)."""
        if not (0 < len(robot_id) <= 64):
            raise FieldError("'robot_id' must have 1 to 64 characters")
        check_specs(b.get("tasks", []))
        r = self.registry.lookup(team, robot_id)
        if r is not None:
            return r
        limit = self.robot_limit(team)
        have = len(self.registry.of_team(team))
        if have >= limit:
            raise ForbiddenError(
                f"team {team} has its {limit} robot{'s' if limit != 1 else ''} already (the scenario gives "
                f"each team {limit}); robot {robot_id!r} is one too many and was not registered. A robot "
                "that comes back registers with its old robot id; the organiser may allow more with "
                "'robo-comp core --robots N'")
        if "x" in b and "y" in b:
            where = self.gate.where(float(b["x"]), float(b["y"]))
            if not where.ok:
                raise ImplausibleError(f"robot {robot_id!r} cannot start there: {where.reason}")
        return None

    def register(self, team: str, robot_id: str, host: Any, b: dict[str, Any]) -> dict[str, Any]:
        """Register robot ``robot_id`` of ``team`` on host ``host`` (a routing id live, the engine's
        own handle on the engine) with the body of a ``register`` message ``b`` (pose, advertised
        tasks, declared speed, the task its host runs and a ``task.done`` it kept); call
        :meth:`admit` first. Returns ``tag``, ``returning``, ``task`` (what the host runs now) and
        ``hold``."""
        specs = check_specs(b.get("tasks", []))
        r = self.registry.lookup(team, robot_id)
        returning = r is not None
        if r is None:
            r = self.registry.add(team, robot_id)
            r.registered_at = self.wall()
            r.radio_allowance, r.radio_checked = RADIO_RATE, self.mono()  # a new robot may radio at once
        r.session = host
        r.tasks = specs
        declared = b.get("speed")
        speed = min(self.max_speed, float(declared)) if declared and declared > 0 else self.default_speed
        r.track.speed, r.track.cap = speed, self.gate.capacity(speed)
        self._registered_pose(r, b, returning)
        was = self.lifecycle.registered(r)
        r.last_report = self.wall()
        if returning:
            done = b.get("done")
            if done is not None and r.current is not None and done.get("task_id") == r.current.id:
                # the host finished it while the match could not hear (the core was down, the link
                # cut): its task.done comes with the registration; taken once, like task.done
                self.take_done(r, done)
            elif r.current is not None and r.current.id != b.get("task_id") and b.get("fresh", True):
                # the host no longer runs what we think it runs (it restarted): start afresh (else the
                # host never got this task, and the reply hands it over again)
                self.tasks.finish(r, r.current, False, "the robot's host restarted and lost this task",
                                  state=TaskState.CANCELLED)
            self.out.emit("robot.returned", r.team, {"tag": r.tag, "x": r.x, "y": r.y, "was": was,
                                                     "tasks": list(specs.values())})
        else:
            self.out.emit("robot.registered", r.team, {"tag": r.tag, "team": r.team, "robot_id": robot_id,
                                                       "x": r.x, "y": r.y, "heading": r.heading,
                                                       "tasks": list(specs.values())})
        self.tasks.advance(r)
        return {"tag": r.tag, "team": r.team, "returning": returning,
                "task": r.current.wire() if r.current else None, "hold": self.contest.holding}

    def _registered_pose(self, r: RobotRecord, b: dict[str, Any], returning: bool) -> None:
        """Take the pose a robot registers with, if it could be there: a new robot anywhere free in
        the arena, a returning one within what it could have driven while it was away (after a core
        restart, anywhere free: this core never placed it)."""
        if "heading" in b:
            r.heading = float(b["heading"])
        if "x" in b and "y" in b:
            x, y = float(b["x"]), float(b["y"])
            verdict = self.gate.admit(r.track, x, y, 0.0, self.mono(), away=returning)
            if verdict.ok:
                r.x, r.y = x, y
            else:
                self.disbelieve(r, "pose", verdict.reason)

    def advertise(self, r: RobotRecord, tasks: Any) -> None:
        """Robot ``r`` advertises ``tasks`` now (after an upload or an unload on its host)."""
        r.tasks = check_specs(tasks)
        self.out.emit("robot.tasks", r.team, {"tag": r.tag, "tasks": list(r.tasks.values())})

    def heard(self, r: RobotRecord) -> None:
        """Robot ``r``'s host spoke for it: a lost robot is back."""
        if r.status is not RobotStatus.CONNECTED:
            self.lifecycle.returned(r)

    def lost(self, r: RobotRecord, why: str) -> None:
        """Robot ``r``'s host went silent or let it go: its tasks are offered to its team
        (:class:`~robo_comp.match.teamwork.TeamWork`)."""
        if self.lifecycle.lost(r, why):
            self.teamwork.robot_gone(r, f"was lost ({why})")

    def leave(self, r: RobotRecord) -> None:
        """Robot ``r``'s host takes it out of the arena: its tasks are offered to its team."""
        was = r.status
        self.lifecycle.left(r)
        r.session = None
        if was is not RobotStatus.LEFT and r.status is RobotStatus.LEFT:
            self.teamwork.robot_gone(r, "left the arena")

    def set_reallocate(self, team: str, on: bool, by: str) -> dict[str, Any]:
        """Turn ``team``'s built-in reallocation of a lost robot's tasks on or off."""
        return self.teamwork.set_reallocate(self.contest.team_arg(team), on, by)

    def video(self, r: RobotRecord, claim: dict[str, Any], **meta: Any) -> dict[str, Any]:
        """Robot ``r`` filmed a video (``claim``: where its host says; judged like a picture's
        place); recorded and announced with the next id."""
        x, y, heading = self.judged_pose(r, claim, "video")
        return self.videos.record(r.team, r.tag, x, y, heading, **meta)

    def obstacle(self, r: RobotRecord, x: Any, y: Any) -> bool:
        """Robot ``r`` reports cell ``(x, y)`` blocked where the map shows it free: on its team's map
        from now on (False: the team knew it already)."""
        self.contest.check_robot(r.tag)
        return self.teamwork.obstacle(r, x, y, self.scenario.walls)

    def halt_and_remove(self, tag: int, reason: str) -> None:
        """Halt robot ``tag`` (no answer awaited), cancel its tasks, take it out of the match."""
        r = self.registry.get(tag)
        if r.status is RobotStatus.CONNECTED:
            self.out.to_host(r, "stop", {"tag": r.tag})
        self.tasks.cancel_all(r, f"cancelled: {reason}", f"cancelled: {reason}")
        self.lifecycle.disqualified(r)

    def disqualify(self, team: Any, tag: Any, reason: str) -> list[int]:
        """The referee takes a team (every robot of it) or one robot out of the match."""
        c = self.contest
        if team is not None:
            team = c.team_arg(team)
            c.board.disqualified.add(team)
            tags = [r.tag for r in self.registry.of_team(team)]
        elif tag is not None:
            tags = [self.registry.get(tag).tag]
        else:
            raise FieldError("disqualify needs a 'tag' or a 'team'")
        for t in tags:
            c.disqualified_robots[t] = reason
            self.halt_and_remove(t, reason)
        self.out.emit("disqualified", "*", {"team": team, "tags": tags, "reason": reason})
        c.score_dirty = True  # the board goes out once, with this turn's other changes
        return tags

    def handed_over(self, r: RobotRecord, by: str, old: str | None) -> None:
        """The referee handed robot ``r`` from its host to the next that registers it."""
        self.lifecycle.lost(r, "handed over by the referee; waiting for its next host")
        r.session = None
        self.out.emit("robot.handover", r.team, {"tag": r.tag, "by": by, "from": old})

    # ------------------------------------------------------------------ tasks
    def _task_started(self, r: RobotRecord, t: TaskRecord) -> None:
        self.out.emit("task.started", r.team, {"tag": r.tag, "task_id": t.id, "name": t.name, "args": t.args})

    def _task_finished(self, r: RobotRecord, t: TaskRecord) -> None:
        self.registry.finished(r, t)
        self.out.emit("task.done", r.team, {"tag": r.tag, "task_id": t.id, "name": t.name, "ok": t.ok,
                                            "state": t.state, "status": t.status, "result": t.result})

    def _give_moved(self, r: RobotRecord, name: str, args: list[Any], by: str,
                    moved_from: dict[str, Any]) -> dict[str, Any]:
        return self.give(r, name, args, True, by, moved_from=moved_from)

    def give(self, r: RobotRecord, name: str, args: list[Any], queue: bool, by: str, *,
             moved_from: dict[str, Any] | None = None) -> dict[str, Any]:
        """Give robot ``r`` a task now (interrupting) or queued; who may is the driver's check.
        Returns the ``give`` reply's body; the host gets ``task.start`` or ``task.interrupt``.
        ``moved_from`` (``tag``, ``task_id``): a lost teammate's task moved here (the ``task.given``
        event says so)."""
        self.contest.check_robot(r.tag)
        self.contest.check_phase("give")
        spec = find_spec(r.tasks, name, r.tag)
        args = check_args(spec, args)
        if r.status is RobotStatus.LEFT:
            raise UnavailableError(f"robot {r.tag} has left the arena; it takes no tasks until it returns")
        if not queue and r.status is not RobotStatus.CONNECTED:
            raise UnavailableError(
                f"robot {r.tag} is {r.status} and cannot start a task now; queue it (--queue) for when it returns")
        t = TaskRecord(self.next_task_id, r.tag, spec["name"], args, TaskMode.QUEUE if queue else TaskMode.NOW, by,
                       given_at=self.wall())
        self.next_task_id += 1
        given = {"tag": r.tag, "task_id": t.id, "name": t.name, "args": args, "mode": t.mode, "by": by}
        if moved_from is not None:
            given["from"] = moved_from
        self.out.emit("task.given", r.team, given)
        started = self.tasks.give(r, t, idle_ok=r.status is RobotStatus.CONNECTED)
        if started is not None:
            self.out.to_host(r, "task.start", started.wire())
        if queue:
            return {"task_id": t.id, "mode": "queue", "position": len(r.queue)}
        if started is t:
            return {"task_id": t.id, "mode": "now", "interrupts": None}
        assert r.current is not None  # t waits for the running task's next movement boundary
        self.out.to_host(r, "task.interrupt", t.wire())
        return {"task_id": t.id, "mode": "now", "interrupts": r.current.id}

    def task_next(self, r: RobotRecord) -> TaskRecord | None:
        """The task robot ``r`` runs now (its next one started if it was idle)."""
        return r.current or self.tasks.advance(r)

    def task_done(self, r: RobotRecord, b: dict[str, Any]) -> dict[str, Any]:
        """Robot ``r``'s host reports its running task ended (``task_id``, ``ok``, ``status``,
        ``result``); a report sent again is taken once. Returns ``next`` (the task it starts now)."""
        tid = b["task_id"]
        if r.current is None or r.current.id != tid:
            if any(t.id == tid for t in r.done):  # sent again (its answer was lost): taken once
                return {"next": r.current.wire() if r.current is not None else None, "duplicate": True}
            raise FieldError(f"task {tid} is not robot {r.tag}'s current task")
        nxt = self.take_done(r, b)
        return {"next": nxt.wire() if nxt is not None else None}

    def take_done(self, r: RobotRecord, b: dict[str, Any]) -> TaskRecord | None:
        """Finish ``r``'s current task with the host's report ``b``; returns the task that starts next."""
        result = b.get("result")
        if len(wire.pack(result)) > MAX_RESULT:
            raise TooLargeError(f"a task result may be at most {MAX_RESULT} bytes once packed")
        if not isinstance(b.get("ok"), bool) or not isinstance(b.get("status"), str):
            raise FieldError("a task's report needs 'ok' (true or false) and 'status' (text)")
        return self.tasks.complete(r, b["ok"], b["status"][:500], result)

    def stopped(self, r: RobotRecord, body: dict[str, Any], ms: float) -> list[int]:
        """Robot ``r``'s host confirmed a stop ``ms`` after it was asked, halted where ``body`` says
        (taken if the robot could be there): its tasks are cancelled; returns their ids."""
        if type(body.get("heading")) in (int, float) and math.isfinite(body["heading"]):
            r.heading = float(body["heading"])
        x: Any = body.get("x")
        y: Any = body.get("y")
        if type(x) in (int, float) and type(y) in (int, float) and not self.pose_refusal(r, x, y, r.sigma, self.mono()):
            r.x, r.y = float(x), float(y)  # where it halted, if it could be there (else where it is tracked)
        r.moving = False
        cancelled = self.tasks.cancel_all(r, "stopped", "cancelled by stop")
        self.out.emit("robot.stopped", r.team, {"tag": r.tag, "x": r.x, "y": r.y, "cancelled": cancelled,
                                                "ms": round(ms, 3)})
        return cancelled

    # ------------------------------------------------------------------ radio
    def radio(self, r: RobotRecord, to: Any, data: Any) -> int:
        """Robot ``r`` radios ``data`` to teammate ``to`` (None: every teammate); returns how many
        connected robots it reached."""
        size = len(wire.pack(data))
        if size > MAX_RADIO:
            raise TooLargeError(f"a radio message may be at most {MAX_RADIO} bytes; this one is {size}")
        now = self.mono()
        r.radio_allowance = min(RADIO_RATE, r.radio_allowance + (now - r.radio_checked) * RADIO_RATE)
        r.radio_checked = now
        if r.radio_allowance < 1.0:
            raise RateLimitError(f"robot {r.tag} may send at most {RADIO_RATE:.0f} radio messages per second")
        r.radio_allowance -= 1.0
        if to is None:
            targets = [x for x in self.registry.of_team(r.team) if x.tag != r.tag]
        else:
            t = self.registry.robots.get(to)
            if t is None or t.team != r.team:
                raise NotYoursError(f"robot {to} is not on team {r.team}; the radio reaches your own team only")
            targets = [t]
        delivered = 0
        body = {"from": r.tag, "to": to, "data": data}
        for t in targets:
            if t.status is RobotStatus.CONNECTED and t.session is not None:
                self.out.to_host(t, "radio", dict(body, tag=t.tag))
                delivered += 1
        self.out.emit("radio", r.team, dict(body, delivered=delivered))
        return delivered

    # ------------------------------------------------------------------ poses and claims
    def judged_pose(self, r: RobotRecord, claim: dict[str, Any], what: str) -> tuple[float, float, float]:
        """The pose at which the match judges ``what`` (a picture, a bump) of robot ``r``: the host's
        ``claim`` only where the tracked pose bears it out (within 3 sigma, plus the driving since the
        last report), else the tracked pose, and the referee gets an ``integrity`` event."""
        tracked = (r.x, r.y, r.heading)
        if not all(type(claim.get(k)) in (int, float) for k in ("x", "y")):
            return tracked
        x, y = float(claim["x"]), float(claim["y"])
        since = self.wall() - r.last_report if r.last_report else self.gate.lag
        verdict = self.gate.bears_out((r.x, r.y), r.sigma, since, r.track.speed, (x, y))
        if not verdict.ok:
            self.disbelieve(r, what, f"{what} {verdict.reason}; judged where it is tracked")
            return tracked
        heading: Any = claim.get("heading")
        if type(heading) in (int, float) and math.isfinite(heading):
            return x, y, float(heading)
        return x, y, r.heading

    def disbelieve(self, r: RobotRecord, kind: str, why: str) -> None:
        """A claim about robot ``r`` (a ``pose``, a ``picture``'s or a ``bump``'s place) was not
        believed: counted, and told to the referee in one ``integrity`` event per robot and kind
        at the next :meth:`tell_integrity`."""
        row = self._implausible.get((r.tag, kind))
        if row is None:
            self._implausible[(r.tag, kind)] = [1, why]
        else:
            row[0] += 1
            row[1] = why

    def tell_integrity(self) -> None:
        """The ``integrity`` events (referee only) of the claims not believed since the last call."""
        if not self._implausible:
            return
        rows, self._implausible = self._implausible, {}
        for (tag, kind), (count, why) in sorted(rows.items()):
            r = self.registry.robots[tag]
            self.out.emit("integrity", None, {"kind": kind, "tag": tag, "team": r.team, "count": count,
                                              "x": r.x, "y": r.y, "message": why})

    def pose_refusal(self, r: RobotRecord, x: float, y: float, sigma: float, now: float) -> str:
        """Why robot ``r`` could not be at ``(x, y)`` now ("" when it could: ``PoseGate.admit``, and
        its track moves on); a refused pose is counted for the referee's ``integrity`` event."""
        verdict = self.gate.admit(r.track, x, y, sigma, now)
        if not verdict.ok:
            self.disbelieve(r, "pose", verdict.reason)
        return verdict.reason

    def report(self, r: RobotRecord, x: float, y: float, heading: float, moving: bool,
               sensors: dict[str, Any] | None) -> None:
        """One robot's pose (a row of :meth:`take_rows`, without its loop): ``E_IMPLAUSIBLE`` if the
        robot could not be there."""
        mono = self.mono()
        if not PoseGate.quick(r.track, x, y, 0.0, mono):
            why = self.pose_refusal(r, x, y, 0.0, mono)
            if why:
                raise ImplausibleError(f"robot {r.tag}'s pose was not taken: {why}")
        r.x, r.y, r.heading, r.moving, r.sigma = x, y, heading, moving, 0.0
        if sensors is not None:
            r.sensors = sensors
        r.last_report = self.wall()
        self.moved.add(r.tag)
        self.posed.setdefault(r.team, set()).add(r.tag)

    def take_rows(self, host: Any, team: str, tags: Sequence[int], xs: Sequence[float], ys: Sequence[float],
                  headings: Sequence[float], moving: Sequence[bool], sensors: Sequence[dict[str, Any] | None],
                  sigmas: Sequence[float]) -> tuple[list[int], list[tuple[int, str]]]:
        """Take the poses of robots of ``team`` run by ``host`` (published in the next position
        batch); returns the tags not run by ``host`` and the refused rows with why. The rows are taken
        in one loop without calls (:meth:`PoseGate.admit`'s common case inlined): a core with 10,000
        robots at 10 Hz takes 100,000 rows a second."""
        now = self.wall()
        mono = self.mono()
        foreign = []
        refused = []
        robots = self.registry.robots
        took: list[int] = []
        taken = took.append
        connected = RobotStatus.CONNECTED
        sqrt = math.sqrt
        max_sigma = MAX_SIGMA
        max_noise = MAX_NOISE
        try:
            for tag, x, y, h, mv, sn, sg in zip(tags, xs, ys, headings, moving, sensors, sigmas):
                r = robots.get(tag)
                if r is None or r.session != host:
                    foreign.append(tag)
                    continue
                if r.status is not connected:
                    self.lifecycle.returned(r)
                # PoseGate.quick inlined (a call a row costs a fifth of the row): the common case of
                # PoseGate.admit. The rest (a new anchor once a second, refusals, longer moves) asks
                # admit, which refills.
                tr = r.track
                until, x_lo, x_hi, y_lo, y_hi = tr.box
                lx, ly, lnoise, left = tr.hop
                dx = x - lx
                dy = y - ly
                noise = 3.0 * sg if sg < max_sigma else max_noise
                hop = sqrt(dx * dx + dy * dy) - lnoise - noise
                if mono < until and x_lo <= x <= x_hi and y_lo <= y <= y_hi and hop <= left:
                    tr.hop = (x, y, noise, left - hop if hop > 0.0 else left)
                else:
                    why = self.pose_refusal(r, x, y, sg, mono)
                    if why:
                        refused.append((tag, why))
                        continue
                r.x = x  # one store each: a five-way tuple assignment builds and unpacks a tuple a row
                r.y = y
                r.heading = h
                r.moving = mv
                r.sigma = sg
                if sn is not None:
                    r.sensors = sn
                r.last_report = now
                taken(tag)
        finally:
            if took:
                self.moved.update(took)
                self.posed.setdefault(team, set()).update(took)
        return foreign, refused

    def position_sample(self, tags: list[int]) -> dict[str, Any]:
        """The log's record of robots ``tags``' poses (a ``robot.positions`` sample)."""
        rows = [self.registry.robots[t] for t in tags]
        return {"tags": tags, "x": [r.x for r in rows], "y": [r.y for r in rows], "heading": [r.heading for r in rows]}

    def position_batch(self, team: str, tags: list[int]) -> dict[str, Any] | None:
        """The live feed's ``robot.positions`` of robots ``tags`` of ``team`` that are connected
        (a robot lost or gone since it reported is left out: its ``robot.lost`` went first)."""
        robots = self.registry.robots
        connected = RobotStatus.CONNECTED
        rows = [r for r in map(robots.__getitem__, tags) if r.status is connected]
        if not rows:
            return None
        return {"team": team, "tags": [r.tag for r in rows], "x": [r.x for r in rows],
                "y": [r.y for r in rows], "heading": [r.heading for r in rows],
                "moving": [r.moving for r in rows], "sigma": [r.sigma for r in rows]}

    # ------------------------------------------------------------------ views
    def snapshot(self, team: str | None) -> dict[str, Any]:
        """What ``team`` (None: the referee) sees of the match now: robots, clock, scores, finds, the
        videos its robots filmed."""
        c = self.contest
        return {"robots": [r.summary() for r in self.registry.of_team(team)], "match": c.state(),
                "score": c.board.table(), "finds": [f for f in c.judge.finds if team is None or f["team"] == team],
                "videos": [v for v in self.videos.records.values() if team is None or v["team"] == team]}


__all__ = ["MAX_RESULT", "MAX_SPEED_FACTOR", "Match"]

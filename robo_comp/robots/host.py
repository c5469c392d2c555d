"""The robot host: one process, one DEALER socket, one poll loop, many simulated robots.

The host says hello with its team token, fetches the arena, registers its robots (each
with a stable robot id, so a reconnect keeps the tag) and then runs a fixed-rate loop:
advance every robot's movement, ask finished tasks for their next step, report positions.
When the core goes silent for three heartbeat intervals every robot halts and the host
reconnects on its own; the robots resume where they were once registered again. The robots run
their tasks in the task runtime (:class:`robo_comp.robots.runtime.TaskRuntime`) that the engine
runs too; this host is its :class:`~robo_comp.robots.runtime.RuntimeEnv`: it plans off its loop
(a host of many robots in a process of its own, :mod:`robo_comp.robots.planning`),
uploads pictures to the core and reports each task's end to it.
"""
from __future__ import annotations

import gc
import logging
import random
import signal
import sys
import time
from collections.abc import Callable
from concurrent.futures import Future
from pathlib import Path
from typing import Any

import numpy as np
import zmq

from robo_comp import protocol as P
from robo_comp.client import open_dealer
from robo_comp.match.plausibility import PoseGate
from robo_comp.protocol.curve import ClientKeys, load_public, secure_client
from robo_comp.protocol.session import ClientSession
from robo_comp.errors import FieldError, RoboCompError
from robo_comp.plugins.manager import get_plugin_manager
from robo_comp.robots.oneworld import Foreign, is_real, merge_readings
from robo_comp.robots.readings import ReadingWatch
from robo_comp.robots.planning import HostPlanner
from robo_comp.robots.runtime import PLANNING, RunningTask, SimRobot, TaskRuntime
from robo_comp.robots.steps import Compute, Plan, TaskSpec
from robo_comp.robots.teamcode import TeamCode
from robo_comp.world.arena import Arena
from robo_comp.world.localization import Localization
from robo_comp.world.mapservice import MapView
from robo_comp.world.planner import warm_up
from robo_comp.world.sensors import warm_up as sensors_warm_up
from robo_comp.world.video import FPS, encode_webm
from robo_comp.world.public import scenario_from_payload
from robo_comp.world.scenario import Scenario

log = logging.getLogger("robo_comp.robots")
#: The longest simulation step, in seconds (a clock that jumps forward is taken as this).
MAX_STEP = 0.5

Reply = Callable[[bool, dict[str, Any]], None]


def _log_refusal(what: str) -> Reply:
    """A reply handler that only logs the core's refusal of ``what``."""
    def on_reply(ok: bool, body: dict[str, Any]) -> None:
        if not ok:
            log.warning("%s refused: %s", what, body.get("message"))
    return on_reply

#: Tags the host's "registered" line names at most.
SAY_TAGS = 12
#: Robots per ``reports`` message; the host looks at the core's socket between two messages
#: (so a stop never waits long behind a big host's reports).
REPORT_CHUNK = 100
#: Seconds of a tick's robot loop between two looks at the core's socket (a stop waits at most
#: about this long behind the loop).
LOOK_EVERY = 0.002


#: Seconds a host waits for its planner process to load its kernels before its robots register.
PLANNER_PATIENCE = 30.0

#: Seconds a connection that is still saying hello and registering gets before the host tries a new
#: one (a link that delays every byte by 150 ms needs about a second for the handshake's round trips).
HANDSHAKE_PATIENCE = 3.0


#: Answers to a task.done that end it: the core judged the report itself. Other refusals (an
#: unknown session after a core restart, a full disk, ...) keep it for the next registration.
DONE_REFUSED = frozenset({"E_FIELD", "E_TOO_LARGE", "E_MALFORMED", "E_NOT_YOURS"})


def collect_tasks(pm: Any) -> dict[str, TaskSpec]:
    """Tasks from every plugin's ``robo_comp_tasks``; a later-registered plugin wins a name."""
    tasks: dict[str, TaskSpec] = {}
    for batch in reversed(pm.hook.robo_comp_tasks()):  # pluggy calls the newest plugin first
        for t in batch:
            tasks[t.name] = t
    return tasks


class RobotHost:
    """Hosts ``count`` simulated robots of one team and keeps them connected to the core."""

    def __init__(self, core_url: str, token: str, count: int, *, prefix: str | None = None,
                 speed: float | None = None, report_hz: float = 10.0, sensor_hz: float = 2.0,
                 tick_hz: float = 20.0, driver: str = "sim", driver_options: dict[str, Any] | None = None,
                 plugins: Any = None, ctx: zmq.Context | None = None, seed: int = 0,
                 truth: Scenario | None = None, curve: ClientKeys | None = None,
                 positioning: str | None = None, truth_pub: str | None = None,
                 camera_key: str | Path | None = None, planner: str = "auto") -> None:
        self.url = core_url
        self.token = token
        self.count = count
        self.prefix = prefix
        self.speed = speed
        self.truth = truth
        self.report_interval = 1.0 / report_hz
        self.sensor_interval = 1.0 / sensor_hz
        #: Standing robots whose readings changed: reported within a sensing period (robots/readings.py).
        self.readings_watch = ReadingWatch(self.sensor_interval)
        self.tick = 1.0 / tick_hz
        self.pm = plugins or get_plugin_manager()
        self.driver_kind = driver
        self.driver_options = dict(driver_options or {})
        #: CurveZMQ keys for a ``--curve`` core (None: plain TCP).
        self.curve = curve
        self.tasks = collect_tasks(self.pm)
        self.ctx = ctx or zmq.Context.instance()
        self.rng = random.Random(seed)
        self.seed = seed
        self.sock: zmq.Socket | None = None
        #: The session with the core (protocol/session.py): hello, the secret, heartbeats, a restarted core.
        self.s = ClientSession(token, "robots")
        self.poller = zmq.Poller()
        self.robots: dict[str, SimRobot] = {}
        self.by_tag: dict[int, SimRobot] = {}
        self.walls = np.zeros((1, 1), dtype=bool)
        #: What the robots' planners avoid: the map's walls and the obstacles the team reported.
        self.blocked = self.walls
        self.team: str | None = None
        self.state = "down"  # down, hello, arena, registering, up
        self.replies: dict[int, Reply] = {}
        self.state_since = 0.0
        self._running = False
        self.reconnects = 0
        self._waiting = 0
        self.holding = False
        self.world: Arena | None = None
        self.loc: Localization | None = None
        #: The team's map as the map service shares it, kept current by pushed deltas.
        self.map = MapView()
        #: Uploaded team code: the sandbox, its modules per robot, the runs of its tasks.
        self.code = TeamCode(self)
        # The host's planner: tasks ``yield Plan(goal)`` and the path is found off the loop, in a
        # process of its own at the lowest priority for a host of PROCESS_FROM robots or more (else
        # in a thread), so that a burst of goTo tasks never holds up a stop, a heartbeat or a report
        # behind hundreds of plans (robo_comp.robots.planning).
        self.planner = HostPlanner.for_host(planner, count)
        #: The robots' tasks run here as they run on the engine (this host is the runtime's env).
        self.runtime = TaskRuntime(self)
        # A real positioning system: the fixes of an overhead camera (robo-comp camera run), instead
        # of the simulated one; and, in simulation, the true poses its synthetic cameras draw.
        self.positioning = positioning
        self.fix_sock: zmq.Socket | None = None
        self._fix_opened = self._fix_heard = 0.0
        #: Fixes refused as implausible (jumps the robot could not drive), and when that was last said.
        self.fixes_refused = 0
        self._fix_warned = 0.0
        self.fix_gate: PoseGate | None = None
        if positioning is not None:
            if camera_key is None:
                raise FieldError(
                    "a robot host takes fixes only from the organiser's camera: give --camera-key with the "
                    "camera's public certificate (STATE/keys/organiser.key, made by 'robo-comp keys'; the "
                    "camera runs with 'robo-comp camera run --key STATE/keys/organiser.key_secret')")
            self._camera_public = load_public(camera_key)
            self._open_fixes()
        self.truth_sock: zmq.Socket | None = None
        if truth_pub is not None:
            self.truth_sock = self.ctx.socket(zmq.PUB)
            self.truth_sock.setsockopt(zmq.LINGER, 0)
            self.truth_sock.setsockopt(zmq.SNDHWM, 10)
            self.truth_sock.bind(truth_pub)
        self.camera_fixes = 0
        #: Bodies of other hosts' robots the camera tracks (one world for real and virtual robots).
        self.foreign = Foreign()
        self._code_fd: int | None = None
        #: Robots another host still holds (E_HELD): asked for again once a heartbeat, quietly.
        self.held: set[str] = set()
        self._held_retry = 0.0
        #: Robots the referee handed over to another host: this host leaves them alone.
        self.released: set[str] = set()
        #: robot id -> its task.done not yet answered by the core (sent again on re-registering).
        self.unacked_done: dict[str, dict[str, Any]] = {}
        #: Videos being written in the host's low-priority thread: (job, robot, task, the request's body).
        self._videos: list[tuple[Future[bytes], SimRobot, RunningTask, dict[str, Any]]] = []

    @property
    def heartbeat(self) -> float:
        """The core's heartbeat interval in seconds."""
        return self.s.heartbeat

    @property
    def session(self) -> str | None:
        """The session secret of the current connection (every message after hello carries it)."""
        return self.s.secret

    FIX_SILENCE = 2.0
    """Seconds without a message from the camera after which the host connects to it afresh."""

    def _open_fixes(self) -> None:
        """Subscribe to the camera's fixes over CurveZMQ with the camera's key pinned: a program
        that binds the camera's address without the organiser's secret key never completes the
        handshake, so none of its fixes arrive. libzmq does not retry a connection whose handshake
        failed, so a silent camera gets a fresh connection every :attr:`FIX_SILENCE` seconds (an
        impostor that held the address must not cut the real camera off for good)."""
        assert self.positioning is not None
        if self.fix_sock is not None:
            self.poller.unregister(self.fix_sock)
            self.fix_sock.close(0)
        self._fix_opened = self._fix_heard = time.monotonic()
        public, secret = zmq.curve_keypair()
        self.fix_sock = self.ctx.socket(zmq.SUB)
        self.fix_sock.setsockopt(zmq.LINGER, 0)
        secure_client(self.fix_sock, ClientKeys(public, secret, self._camera_public))
        for topic in (b"fixes", b"camera"):
            self.fix_sock.setsockopt(zmq.SUBSCRIBE, topic)
        self.fix_sock.connect(self.positioning)
        self.poller.register(self.fix_sock, zmq.POLLIN)  # a fix wakes the loop

    # ------------------------------------------------------------------ sending
    def _send(self, type_: str, body: dict[str, Any], on_reply: Reply | None = None) -> None:
        assert self.sock is not None
        rid, frame = self.s.frame(type_, body, time.monotonic())
        if on_reply is not None:
            self.replies[rid] = on_reply
        self.sock.send(frame)

    def _notify(self, type_: str, body: dict[str, Any], sock: zmq.Socket | None = None) -> None:
        """A message that wants no answer (reports, printed lines), on ``sock`` (default: the host's)."""
        sock = sock or self.sock
        assert sock is not None
        sock.send(self.s.frame(type_, body, time.monotonic(), rid=0)[1])

    def _answer(self, rid: int, body: dict[str, Any]) -> None:
        assert self.sock is not None
        self.sock.send(P.ok_reply(rid, body, self.s.secret))
        self.s.last_tx = time.monotonic()

    # ------------------------------------------------------------------ connection
    def _open(self) -> None:
        """Open a fresh socket and say hello (the rest follows from the replies)."""
        if self.sock is not None:
            self.poller.unregister(self.sock)
            self.sock.close(0)
        self.sock = open_dealer(self.ctx, self.url, self.curve, self.token, SNDHWM=100_000, RCVHWM=100_000)
        self.poller.register(self.sock, zmq.POLLIN)
        self.replies.clear()
        self._set_state("hello")
        rid, frame = self.s.hello(self.s.last_rx)  # a new connection opens a new session
        self.replies[rid] = self._on_hello
        self.sock.send(frame)

    def _set_state(self, state: str) -> None:
        self.state = state
        self.state_since = time.monotonic()

    def _on_whole_map(self, ok: bool, body: dict[str, Any]) -> None:
        """The whole map, asked for again after a delta that did not fit."""
        if ok:
            self.map.apply(body)
            self._map_obstacles()

    def _map_obstacles(self) -> None:
        """The obstacles the team's map holds go onto what the planners avoid."""
        h, w = self.blocked.shape
        for x, y in self.map.obstacles:
            if 0 <= x < w and 0 <= y < h:
                self.blocked[y, x] = True

    def _on_hello(self, ok: bool, body: dict[str, Any]) -> None:
        if not ok:
            raise SystemExit(f"robots: the core refused us: {body.get('message')}")
        self.team = body["team"]
        self.s.opened(body)
        self._set_state("arena")
        self._send("arena", {}, self._on_arena)

    def _on_arena(self, ok: bool, body: dict[str, Any]) -> None:
        if not ok:
            raise SystemExit(f"robots: cannot fetch the arena: {body.get('message')}")
        if self.world is None:
            self._build_world(body)
        if not self.robots:
            self._create_robots(body)
        self._set_state("registering")
        mine = [r for r in self.robots.values() if r.robot_id not in self.released]
        self._waiting = len(mine)  # replies still to come before we are "up"
        if not mine:
            self._set_state("up")
        for r in mine:
            self._register(r)

    def _register(self, r: SimRobot) -> None:
        """Register robot ``r`` (again) with its pose, tasks, top speed and the task it runs."""
        b = r.driver
        assert self.world is not None
        self._send("register", {"token": self.token, "robot_id": r.robot_id, "tasks": self.adverts(r.tag),
                                "x": b.x, "y": b.y, "heading": b.heading, "speed": float(self.world.speed),
                                "task_id": r.task.id if r.task else None, **self._resend(r)},
                   lambda ok, body: self._on_registered(r, ok, body))

    def adverts(self, tag: int) -> list[dict[str, Any]]:
        """What robot ``tag`` advertises: the plugins' tasks, then its uploaded code's (which win)."""
        tasks = {name: t.advert() for name, t in self.tasks.items()}
        if tag:
            tasks.update(self.code.adverts(tag))
        return list(tasks.values())

    def _spec(self, tag: int, name: str) -> TaskSpec | None:
        """The task ``name`` as robot ``tag`` runs it: uploaded code first (it may replace a built-in)."""
        return self.code.task_spec(tag, name) or self.tasks.get(name)

    # ------------------------------------------------------------------ team code (teamcode.py calls these)
    def upload_answered(self, rid: int, results: list[dict[str, Any]]) -> None:
        """Answer the core's ``upload`` request ``rid`` with a verdict per robot (and, for the
        robots that took the module, what they advertise now)."""
        for row in results:
            if row.get("ok") and row.get("tag") in self.by_tag:
                row["advertised"] = self.adverts(row["tag"])
        self._answer(rid, {"results": results})

    def tasks_changed(self, tags: list[int]) -> None:
        """Tell the core what these robots advertise now (after a load or an unload)."""
        for tag in tags:
            if tag in self.by_tag:
                self._send("advertise", {"tag": tag, "tasks": self.adverts(tag)},
                           _log_refusal("advertise"))

    def team_log(self, tag: int | None, stream: str, text: str) -> None:
        """Forward a line team code printed (or a sandbox notice) to the team's consoles."""
        if self.state == "up" and self.sock is not None:
            self._notify("log", {"tag": tag if tag in self.by_tag else None, "stream": stream, "text": text[:2000]})

    def team_draw(self, tags: list[int], frames: list[list[Any]]) -> None:
        """Send the robots' new frames of debug drawing to the core (for the team's views only)."""
        if self.state == "up" and self.sock is not None:
            self.sock.send(P.request("draw", 0, {"tags": tags, "frames": frames}, self.session))

    def code_request(self, type_: str, body: dict[str, Any], on_reply: Reply) -> None:
        """A request to the core on behalf of team code (a find, the radio, an obstacle: on this
        host's map at once)."""
        if type_ == "obstacle" and 0 <= body["y"] < self.blocked.shape[0] and 0 <= body["x"] < self.blocked.shape[1]:
            self.blocked[body["y"], body["x"]] = True
        self._send(type_, body, on_reply)

    def code_picture(self, r: SimRobot, on_reply: Reply) -> None:
        """Take and upload a picture for team code; ``on_reply`` gets the picture's id."""
        assert self.world is not None
        png = self.world.camera(r.robot_id)
        x, y, heading = r.driver.truth()
        self._send("picture", {"tag": r.tag, "x": x, "y": y, "heading": heading, "png": png,
                               "label": "team code"}, on_reply)

    def _on_code_request(self, type_: str, rid: int, body: dict[str, Any]) -> None:
        """``upload``, ``unload`` and ``extensions`` from the core."""
        tags = [t for t in body.get("tags") or [] if t in self.by_tag]
        if type_ == "upload":
            self.code.upload(rid, tags, str(body.get("filename")), body.get("source") or "")
        elif type_ == "unload":
            done = self.code.unload(tags, str(body.get("name")))
            self._answer(rid, {"unloaded": done})
            self.tasks_changed(done)
        elif type_ == "sandbox.reset":
            self._answer(rid, {"results": self.code.reset(tags)})
        else:
            self._answer(rid, {"tag": tags[0] if tags else None,
                               "modules": self.code.modules(tags[0]) if tags else []})

    def _build_world(self, arena: dict[str, Any]) -> None:
        """The simulated arena: the organiser's scenario (with victims) or the public one."""
        public = scenario_from_payload(arena)
        scenario = public
        if self.truth is not None:
            if self.truth.walls.shape != public.walls.shape or (self.truth.walls != public.walls).any():
                raise SystemExit("robots: --scenario does not match the core's arena (different walls)")
            scenario = self.truth
        self.world = Arena(scenario, capacity=max(16, self.count))
        if self.speed:
            self.world.speed = self.speed
        self.loc = Localization(self.world, external=self.positioning is not None)
        self.walls = scenario.walls  # the map's (the arena's debris is for the robots' sensors to find)
        self.blocked = self.walls.copy()
        self.fix_gate = PoseGate(self.walls, self.world.speed * float(self.world.speed_map.max(initial=1.0)))

    def _create_robots(self, arena: dict[str, Any]) -> None:
        assert self.world is not None and self.team is not None and self.loc is not None  # made with the world
        start = [c for c in self.world.free_start_cells(self.team)] if any(
            t["name"] == self.team and t.get("start") for t in arena.get("teams", [])) else []
        taken = set(start)
        free = [(x, y) for y, x in np.argwhere(~self.world.walls).tolist() if (x, y) not in taken]
        need = max(0, min(self.count - len(start), len(free)))
        cells = start + self.rng.sample(free, need)  # seeded: the same cells for the same seed
        prefix = self.prefix or self.team
        if self.count > len(cells):
            raise SystemExit(f"robots: the arena has room for {len(cells)} robots, not {self.count}")
        for i in range(self.count):
            x, y = cells[i]
            rid = f"{prefix}-{i + 1}"
            self.world.add_robot(rid, self.team, x, y, 0.0)
            driver = self.pm.hook.robo_comp_driver(kind=self.driver_kind, options={
                **self.driver_options, "arena": self.world, "localization": self.loc, "robot_id": rid,
                "index": i, "cell_cm": self.world.cell_size, "x": float(x), "y": float(y), "heading": 0.0})
            if driver is None:
                raise SystemExit(f"robots: no plugin provides the driver {self.driver_kind!r}")
            self.robots[rid] = SimRobot(rid, driver, self)
        self.loc.update()
        if self.robots:  # compile/load the sensor kernels now, not in the middle of a report
            sensors_warm_up()
            self.world.sense_many([next(iter(self.robots))])

    def _resend(self, r: SimRobot) -> dict[str, Any]:
        """What a registration carries besides the robot: whether this host registers it for the
        first time, and the task.done the core has not acknowledged (the core takes it once)."""
        extra: dict[str, Any] = {"fresh": not r.tag}
        done = self.unacked_done.get(r.robot_id)
        if done is not None:
            extra["done"] = {k: done[k] for k in ("task_id", "ok", "status", "result")}
        return extra

    def _on_registered(self, r: SimRobot, ok: bool, body: dict[str, Any]) -> None:
        if not ok and body.get("code") == "E_HELD":
            if r.robot_id not in self.held:  # said once; asked again quietly once a heartbeat
                log.warning("robot %s: %s", r.robot_id, body.get("message"))
                # another connection runs it for the core: it holds still and reports nothing (its task,
                # if the core still has one, comes back with the registration that takes it)
                self.runtime.halt(r)
                self.by_tag.pop(r.tag, None)
            self.held.add(r.robot_id)
        elif not ok:
            log.error("robot %s was refused: %s", r.robot_id, body.get("message"))
        else:
            if r.robot_id in self.held:
                self.held.discard(r.robot_id)
                log.warning("robot %s: the other host let it go; this host runs it now", r.robot_id)
            self.unacked_done.pop(r.robot_id, None)  # the core has it (or had it already)
            if r.tag and r.tag != body["tag"]:
                self.by_tag.pop(r.tag, None)
            r.tag = body["tag"]
            self.by_tag[r.tag] = r
            self.code.add_tag(r.tag)
            self.holding = bool(body.get("hold", False))
            task = body.get("task")
            if task is None:
                if r.task is not None:  # the core no longer knows our task (it restarted)
                    r.task = None
                    r.driver.halt()
            elif r.task is None or r.task.id != task["task_id"]:
                self.runtime.start(r, task)
        self._waiting -= 1
        if self._waiting <= 0:
            self._set_state("up")
            self._say_up()

    def _say_up(self) -> None:
        """One line on stdout when the robots are registered (again, after a reconnect), so the
        person who started the host sees it work."""
        all_tags = sorted(r.tag for r in self.robots.values() if r.tag)
        tags = ", ".join(map(str, all_tags[:SAY_TAGS]))
        if len(all_tags) > SAY_TAGS:  # a host of a thousand robots says one line, not a page
            tags += f", ... {all_tags[-1]} ({len(all_tags)} tags)"
        again = f" again (reconnect {self.reconnects}: the core is back)" if self.reconnects else ""
        print(f"robots: team {self.team}: {len(self.robots)} robot(s) registered{again} with the core at "
              f"{self.url}; tags {tags or '-'}", flush=True)

    def _lost_core(self, now: float) -> None:
        """Halt every robot and start reconnecting."""
        self._reconnect(f"lost the core (silent for {now - self.s.last_rx:.1f} s)")

    def _reconnect(self, why: str) -> None:
        """Hello and register again on a fresh socket; robots hold still meanwhile."""
        log.warning("%s; halting robots and reconnecting", why)
        for r in self.robots.values():  # a real robot's driver stands it still now (a simulated one
            pause = getattr(r.driver, "pause", None)  # stands still while step() does not run)
            if pause is not None:
                pause()
        # Movement pauses while we are not "up": step() only runs then; the robots resume
        # their current steps once registered again.
        self.reconnects += 1
        self._open()

    # ------------------------------------------------------------------ messages from the core
    def _dispatch(self, frame: bytes) -> None:
        try:
            msg = P.unpack(frame)
            checked = P.validate_to_host(msg)  # the field table of what the core sends hosts
        except Exception as e:
            self.s.last_rx = time.monotonic()
            log.error("a message from the core that this host cannot take, ignored: %s",
                      getattr(e, "message", None) or e.__class__.__name__)
            return
        type_, rid = checked.type, checked.id
        body = msg.get("body") or {}
        over = self.s.heard(msg, time.monotonic())
        if over is not None and self.state == "up":  # the core forgot this session, or restarted
            self._reconnect(over.value)
            return
        if type_ == "reply":
            exc = P.reply_error(msg)
            cb = self.replies.pop(rid, None)
            if cb is not None:  # an error reaches the callback as {"code", "message", "details"}
                cb(exc is None, body if exc is None else {"code": exc.code, "message": exc.message,
                                                        "details": exc.details})
            elif exc is not None:
                log.warning("core: %s", exc.message)
            return
        if type_ == "heartbeat":
            return
        if type_ == "event":
            return
        if type_ == "release":  # the referee handed a robot to another host: halt it and let it go
            gone = self.by_tag.pop(body.get("tag", -1), None)
            if gone is not None:
                self.runtime.halt(gone)
                gone.task = None
                gone.tag = 0
                self.released.add(gone.robot_id)
                log.warning("robot %s: %s; this host no longer runs it", gone.robot_id,
                            body.get("message", "released by the core"))
            return
        if type_ == "hold":  # the match is paused or over: robots hold still, tasks wait
            self.holding = bool(body.get("on"))
            return
        if type_ == "map.delta":
            try:
                self.map.apply(body)
                self._map_obstacles()
            except Exception as e:  # a delta that does not fit our version: ask for all again
                log.warning("map delta not applied (%s); fetching the whole map", e)
                self._send("map.delta", {"since": 0}, self._on_whole_map)
            return
        if type_ in ("upload", "unload", "extensions", "sandbox.reset"):
            self._on_code_request(type_, rid, body)
            return
        r = self.by_tag.get(body.get("tag", -1))
        if type_ == "stop":
            if r is None:
                assert self.sock is not None  # the stop came in on it
                self.sock.send(P.error_reply(rid, RoboCompError("no such robot on this host"), self.s.secret))
                return
            self.runtime.halt(r)
            self._answer(rid, {"tag": r.tag, "x": r.driver.x, "y": r.driver.y, "heading": r.driver.heading})
        elif type_ == "radio" and r is not None:
            r.inbox.append({"from": body.get("from"), "data": body.get("data")})
        elif type_ == "task.start" and r is not None:
            if r.task is None or r.task.id != body["task_id"]:
                if r.task is not None:
                    r.driver.halt()
                self.runtime.start(r, body)
        elif type_ == "task.interrupt" and r is not None:
            self.runtime.interrupt(r, body)

    # ------------------------------------------------------------------ the runtime's env (RuntimeEnv)
    def spec(self, r: SimRobot, name: str) -> TaskSpec | None:
        """Task ``name`` as robot ``r`` runs it: uploaded code first (it may replace a built-in)."""
        return self._spec(r.tag, name)

    def plan(self, r: SimRobot, step: Plan) -> Any:
        """Plan off the loop (the host's planner process or thread): the robot waits at its boundary."""
        occupied = r.others_cells() if step.avoid_robots else set()
        assert r.task is not None
        r.task.plan = self.planner.plan(self.blocked, r.free_cell(), step.goal, occupied)
        return PLANNING

    def compute(self, r: SimRobot, step: Compute) -> bool:
        """Team code computes: the robot waits a tick (the sandbox is pumped by the loop)."""
        return False

    def interrupted(self, r: SimRobot, t: RunningTask, by_task_id: int) -> None:
        """The plugins hear of an interrupt before it takes effect."""
        self.pm.hook.robo_comp_task_interrupted(robot=r, task_name=t.name, task_id=t.id, by_task_id=by_task_id)

    def obstacle(self, r: SimRobot, cell: tuple[int, int]) -> None:
        """On this host's map at once, and to the core for the team's map (its other hosts get it
        with the next ``map.delta``)."""
        x, y = cell
        self.blocked[y, x] = True
        self._send("obstacle", {"tag": r.tag, "x": x, "y": y}, _log_refusal("obstacle"))

    def capture(self, r: SimRobot, t: RunningTask, label: str) -> None:
        """Take the camera picture at the robot's true pose and upload it as evidence."""
        assert self.world is not None
        png = self.world.camera(r.robot_id)
        x, y, heading = r.driver.truth()
        self._send("picture", {"tag": r.tag, "x": x, "y": y, "heading": heading, "png": png,
                               "label": label[:64]},
                   lambda ok, body: self._on_picture(t, ok, body))

    def frame(self, r: SimRobot) -> Any:
        """A frame of the camera at the robot's true pose (the simulated arena's view)."""
        assert self.world is not None
        return self.world.camera_image(r.robot_id)

    def video(self, r: SimRobot, t: RunningTask, frames: list[Any], label: str) -> None:
        """Written as WebM in the host's low-priority thread (a second of the loop's time otherwise), then sent
        to the core from the loop (:meth:`_send_videos`); its id goes into the task's result."""
        x, y, heading = r.driver.truth()
        t.uploads += 1
        job = self.planner.run(encode_webm, frames)
        self._videos.append((job, r, t, {"tag": r.tag, "x": x, "y": y, "heading": heading, "label": label,
                                         "frames": len(frames), "seconds": round(len(frames) / FPS, 3)}))

    def _send_videos(self) -> None:
        """Send the videos written since the last look."""
        waiting = []
        for job, r, t, body in self._videos:
            if not job.done():
                waiting.append((job, r, t, body))
                continue
            try:
                data = job.result()
            except RoboCompError as e:
                t.uploads -= 1
                log.warning("robot %s: no video: %s", r.robot_id, e.message)
                continue
            self._send("video", dict(body, webm=data), self._video_reply(t))
        self._videos = waiting

    @staticmethod
    def _video_reply(t: RunningTask) -> Reply:
        """What the core's answer to a video does: its id into the task's result."""
        def on_reply(ok: bool, body: dict[str, Any]) -> None:
            t.uploads -= 1
            if ok:
                t.videos.append(body["id"])
            else:
                log.warning("video refused: %s", body.get("message"))
        return on_reply

    @staticmethod
    def _on_picture(t: RunningTask, ok: bool, body: dict[str, Any]) -> None:
        """The core kept the picture: its id becomes evidence in the task's result."""
        if ok:
            t.pictures.append(body["id"])
        else:
            log.warning("picture refused: %s", body.get("message"))

    def task_ended(self, r: SimRobot, task_id: int, ok: bool, status: str, result: Any) -> None:
        """Report a task's end to the core (kept until it answers)."""
        self._report_one(r, time.monotonic())  # the owner sees the final pose with the result
        done = {"tag": r.tag, "task_id": task_id, "ok": ok, "status": status, "result": result}
        # kept until the core answers: a core that goes down before it does gets it again with
        # the robot's registration after the reconnect
        self.unacked_done[r.robot_id] = done
        self._send("task.done", done, lambda ok_, body: self._on_done_reply(r, task_id, ok_, body))

    def _on_done_reply(self, r: SimRobot, task_id: int, ok: bool, body: dict[str, Any]) -> None:
        held = self.unacked_done.get(r.robot_id)
        if held is not None and held["task_id"] == task_id and (ok or body.get("code") in DONE_REFUSED):
            del self.unacked_done[r.robot_id]  # taken, or refused for what it says (not for who sent it)
        nxt = body.get("next") if ok else None
        if nxt is not None and r.task is None:
            self.runtime.start(r, nxt)

    # ------------------------------------------------------------------ loop
    def _clock_went_back(self, now: float) -> None:
        """The monotonic clock jumped back (an injected clock, a restored VM): every time stamp taken
        before is in the future now, and would hold back heartbeats, reports and sensing until the
        clock caught up. Take them all as now."""
        log.warning("the clock went back; the host goes on from now")
        self.s.last_tx = self.s.last_rx = self.state_since = now
        for r in self.robots.values():
            r.last_report = min(r.last_report, now)
            r.last_sensed = min(r.last_sensed, now)

    def step(self, dt: float) -> None:
        """Advance the arena and every robot by ``dt`` seconds (movement, task steps)."""
        assert self.world is not None and self.loc is not None
        for ev in self.world.step(dt):
            if ev.kind == "bump":
                r = self.robots[ev.tag]
                r.driver.bump = ev.data
                if r.tag:
                    other = self.robots.get(ev.data.get("other") or "")
                    self._send("bump", {"tag": r.tag, "x": ev.data["x"], "y": ev.data["y"],
                                        "with": other.tag if other else None})
        self.loc.update()
        # The core's socket is looked at every LOOK_EVERY seconds of this loop, so a stop does not
        # wait for hundreds of robots' moves to begin. Only the steps under way when the tick began
        # advance: a task a message starts meanwhile begins its first step next tick, as it would
        # have had the message come after the tick.
        look = time.perf_counter() + LOOK_EVERY
        for r, step in [(r, r.driver.step) for r in self.robots.values()]:
            if is_real(r.driver):  # runs without a step too: it reads odometry and scans
                if r.driver.step is None:
                    r.driver.update(dt)
                self.world.place(r.robot_id, self.team or "", *r.driver.pose)
            if step is not None and r.driver.step is step and r.driver.update(dt):
                self.runtime.boundary(r)
            if time.perf_counter() >= look:
                self._drain()
                look = time.perf_counter() + LOOK_EVERY
        if self.runtime.planning:
            self.runtime.take_plans()
        if self.runtime.filming:
            self.runtime.film(dt)
        if self._videos:
            self._send_videos()
        if self.foreign.seen:
            self.foreign.expire(self.world, time.monotonic())

    def _report_one(self, r: SimRobot, now: float) -> None:
        """Report what one robot believes (the positioning system's estimate) at once, and
        its sensor readings when they are due."""
        sensors = None
        if now - r.last_sensed >= self.sensor_interval:
            sensors = self._sense([r]).get(r.tag)
        body = self._pose_rows([r], now, {r.tag: sensors} if sensors is not None else {})
        assert self.sock is not None  # a task ends on a connected host (its task.done follows on this socket)
        self._notify("reports", body)

    def _pose_rows(self, robots: list[SimRobot], now: float,
                   readings: dict[int, dict[str, Any]]) -> dict[str, Any]:
        """The body of one ``reports`` message for ``robots`` (sensors where ``readings`` has them)."""
        tags, xs, ys, hs, moving, sensors, sigmas = [], [], [], [], [], [], []
        loc = self.loc
        for r in robots:
            r.last_report = now
            x, y, heading = r.driver.pose
            tags.append(r.tag)
            xs.append(round(x, 3))
            ys.append(round(y, 3))
            hs.append(round(heading, 1))
            moving.append(r.driver.moving)
            sigmas.append(round(loc.sigma(r.robot_id), 3) if loc is not None else 0.0)
            s = readings.get(r.tag)
            if s is not None:
                r.last_sensed = now
                self.readings_watch.sent(r.robot_id, s)
            sensors.append(s)
        body: dict[str, Any] = {"tags": tags, "x": xs, "y": ys, "heading": hs, "moving": moving, "sigma": sigmas}
        if readings:
            body["sensors"] = sensors
        return body

    def _sense(self, robots: list[SimRobot]) -> dict[int, dict[str, Any]]:
        """Sensor readings of ``robots`` by tag: the simulated arena's (one vectorised pass), with
        what ``robo_comp_sense`` plugins add merged in (called only when a plugin implements it)."""
        readings: dict[int, dict[str, Any]] = {}
        if self.world is not None:
            rows = self.world.sense_many([r.robot_id for r in robots])
            readings = {r.tag: row for r, row in zip(robots, rows)}
            for r in robots:  # a real robot's own sensors (a ROS 2 robot's scan) and the virtual world's
                own = getattr(r.driver, "readings", None)
                if own is not None:
                    readings[r.tag] = merge_readings(readings[r.tag], own())
        # each plugin on its own: one that raises loses its readings only, not the others'
        for impl in self.pm.hook.robo_comp_sense.get_hookimpls():
            for r in robots:
                try:
                    part = impl.function(*(r for _ in impl.argnames))  # the one argument: robot
                except Exception:
                    log.exception("plugin %s: robo_comp_sense failed", impl.plugin_name)
                    break
                if isinstance(part, dict) and part:
                    readings.setdefault(r.tag, {}).update(part)
        return readings

    def _report(self, now: float) -> None:
        """Report moving robots every report interval, idle ones once a second and when their
        readings changed (within a sensing period, :mod:`robo_comp.robots.readings`), in ``reports``
        messages of up to ``REPORT_CHUNK`` robots; the sensors of each message's robots due are read in
        one vectorised pass."""
        due: list[SimRobot] = []
        standing: list[SimRobot] = []
        for r in self.by_tag.values():
            (due if r.driver.moving or now - r.last_report >= 1.0 else standing).append(r)
        changed = self.readings_watch.changed(self.world, standing, now)
        if not due and not changed:
            return
        sensing = {r.tag for r in due if now - r.last_sensed >= self.sensor_interval}
        sensing.update(r.tag for r in changed)
        due += changed
        sock = self.sock
        assert sock is not None  # reports go out while the host is up
        for start in range(0, len(due), REPORT_CHUNK):
            if start:
                self._drain()  # many robots: let a stop in between, it must not wait for all reports
                if self.sock is not sock:  # reconnected meanwhile: the robots register again first
                    return
            chunk = due[start:start + REPORT_CHUNK]
            sense = [r for r in chunk if r.tag in sensing]  # read chunk by chunk, a stop in between
            readings = self._sense(sense) if sense else {}
            body = self._pose_rows(chunk, now, readings)
            self._notify("reports", body, sock)

    def _drain(self) -> None:
        """Handle what the core has sent, without waiting (also between chunks of a tick's work);
        a reconnect that replaces the socket mid-way ends it."""
        sock = self.sock
        while sock is not None and sock is self.sock:
            try:
                frame = sock.recv(zmq.NOBLOCK)
            except zmq.Again:
                return
            self._dispatch(frame)

    def _take_fixes(self) -> None:
        """Correct this host's robots with the camera's fixes (a fix for a robot this host does not
        host is not its to take: a team's host moves its own robots only)."""
        assert self.fix_sock is not None
        while True:
            try:
                topic, body = self.fix_sock.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                now = time.monotonic()
                if now - self._fix_heard > self.FIX_SILENCE and now - self._fix_opened > self.FIX_SILENCE:
                    self._open_fixes()
                return
            except ValueError:  # not two frames: not the camera's
                continue
            self._fix_heard = time.monotonic()
            try:
                msg = P.unpack(body)
                if topic == b"camera":
                    log.warning("positioning: %s", str(msg.get("message"))[:300])
                    continue
                fixes = msg["fixes"]
                t = float(msg["t"])
            except Exception:
                log.warning("positioning: an unreadable message from the camera; ignored")
                continue
            if self.loc is None:
                continue
            moved: dict[int, SimRobot] = {}
            for f in fixes if isinstance(fixes, list) else ():
                try:
                    rid = f["robot"]
                    r = self.robots.get(rid)
                    if r is None and self.world is not None and isinstance(rid, str):  # another host's robot:
                        self.foreign.fix(self.world, rid, float(f["x"]), float(f["y"]),  # a body in this arena
                                         float(f["heading"]), time.monotonic())
                    if r is not None and not self._fix_plausible(r, float(f["x"]), float(f["y"]), float(f["sigma"])):
                        continue
                    if r is not None:
                        own_fix = getattr(r.driver, "camera_fix", None)  # a real robot's pose follows the camera
                        if own_fix is not None:
                            own_fix(float(f["x"]), float(f["y"]), float(f["heading"]))
                        before = self.loc.estimate(rid)
                        self.loc.camera_fix(rid, float(f["x"]), float(f["y"]), float(f["heading"]),
                                            float(f["sigma"]), t)
                        self.camera_fixes += 1
                        after = self.loc.estimate(rid)
                        if abs(after[0] - before[0]) + abs(after[1] - before[1]) > 0.05 and r.tag:
                            moved[r.tag] = r  # moved by the fix: reported now, not at the next tick
                except (KeyError, TypeError, ValueError):
                    continue
            if moved and self.state == "up" and self.sock is not None:
                rows = list(moved.values())
                self._notify("reports", self._pose_rows(rows, time.monotonic(), {}))

    def _fix_plausible(self, r: SimRobot, x: float, y: float, sigma: float) -> bool:
        """Whether a camera fix of robot ``r`` is one it could have driven to since the fixes taken
        before (``PoseGate.admit``, the core's rule for reports; the first fix is measured from where
        the robot started); a refused fix is counted and said once a second."""
        gate = self.fix_gate
        if gate is None:
            return True
        now = time.monotonic()
        if r.fix is None:  # placed where it started, with the budget of a robot at rest
            r.fix = gate.track(gate.speed)
            x0, y0, _ = r.driver.pose
            gate.admit(r.fix, x0, y0, 0.0, now)
        verdict = gate.admit(r.fix, x, y, sigma, now)
        if not verdict.ok:
            self.fixes_refused += 1
            if now - self._fix_warned > 1.0:
                self._fix_warned = now
                log.warning("positioning: a fix of %s was refused: %s (%d refused so far)", r.robot_id,
                            verdict.reason, self.fixes_refused)
            return False
        return True

    def _publish_truth(self) -> None:
        """The robots' true poses for synthetic cameras (simulation only: ``--truth-pub``)."""
        assert self.truth_sock is not None and self.world is not None
        w = self.world
        robots = []
        for rid, r in self.robots.items():
            if is_real(r.driver):  # its truth is the real world's (a simulated ROS 2 robot publishes its own)
                continue
            p = w.pose(rid)
            robots.append([rid, round(p.x, 4), round(p.y, 4), round(p.heading, 3)])
        h, wd = w.walls.shape
        body = {"w": wd, "h": h, "walls": np.packbits(w.walls.astype(bool), axis=None).tobytes(), "robots": robots}
        try:
            self.truth_sock.send_multipart([b"truth", P.pack(body)], zmq.NOBLOCK)
        except zmq.Again:
            pass

    def stop(self) -> None:
        """End the loop after the current turn."""
        self._running = False

    def run(self, duration: float | None = None, leave: bool = True) -> None:
        """Connect and serve until :meth:`stop`, a signal, or ``duration`` seconds."""
        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                signal.signal(sig, lambda *_: self.stop())
            except ValueError:
                pass
        t_end = None if duration is None else time.monotonic() + duration
        self._running = True
        self.planner.start()  # the planner process starts and loads its kernels meanwhile
        warm_up(jumps=False)  # load the compiled planner before the robots exist (they plan 4-connected)
        if self.planner.use_process and not self.planner.wait_ready(PLANNER_PATIENCE):
            log.warning("the planner process is not up after %.0f s: planning in the host's thread until it is",
                        PLANNER_PATIENCE)
        gc.collect()  # long-lived modules and kernels out of the collector's way (see Core.run)
        gc.freeze()
        gc.set_threshold(20_000, 50, 100)
        # The thread that writes videos (and plans when the planner process cannot) holds the GIL in its
        # numpy glue: make the loop's wait for it short
        # (CPython's default lets a thread keep it 5 ms before it must hand it over).
        sys.setswitchinterval(0.0005)
        self.s.last_rx = time.monotonic()
        self._open()
        last = time.monotonic()
        next_tick = last + self.tick
        next_report = last
        while self._running and (t_end is None or time.monotonic() < t_end):
            self._watch_code()
            if next_tick - time.monotonic() > self.tick:  # the clock went back: tick now, not an hour on
                last = next_tick = next_report = time.monotonic()
                self._clock_went_back(last)
            wake = next_tick
            code_deadline = self.code.deadline()
            if code_deadline is not None:
                wake = min(wake, code_deadline)
            if self.poller.poll(int(max(0.0, wake - time.monotonic()) * 1000)):  # pyzmq truncates a float the same way
                self._drain()
            if self.fix_sock is not None:
                self._take_fixes()
            try:
                self.code.pump()
            except Exception:  # a bug on the team-code path must not take the robots down
                log.exception("team code: unexpected error while serving the sandbox")
            now = time.monotonic()
            if now >= next_tick:
                if self.state == "up" and not self.holding:
                    # a clock that jumps (a virtual machine resumed, an injected clock) never moves a
                    # robot backwards or across the arena in one step
                    self.step(min(max(0.0, now - last), MAX_STEP))
                    if self.truth_sock is not None:
                        self._publish_truth()
                    self._drain()  # a stop that came in meanwhile goes first
                    if now >= next_report:
                        self._report(now)
                        next_report = now + self.report_interval
                last = now
                next_tick = now + self.tick
                if self.state == "up" and self.s.beat_due(now):
                    self._send("heartbeat", {})
                if self.held and self.state == "up" and now >= self._held_retry:
                    self._held_retry = now + self.heartbeat
                    for rid in list(self.held):
                        if rid in self.robots and rid not in self.released:
                            self._register(self.robots[rid])
                # connecting takes handshake round trips (PLAIN or CURVE, then hello and register): on
                # a slow link a fresh connection gets HANDSHAKE_PATIENCE before it is given up
                beats = 3 * self.heartbeat
                patience = beats if self.state == "up" else max(beats, HANDSHAKE_PATIENCE)
                if self.s.silent(now) and now - self.state_since > patience:
                    self._lost_core(now)
        if leave and self.state == "up":
            for r in self.by_tag.values():
                self._send("leave", {"tag": r.tag})
            time.sleep(0.05)
        self.code.close()
        for r in self.robots.values():  # a real robot's driver stops it and lets go of its link
            close = getattr(r.driver, "close", None)
            if close is not None:
                close()
        self.planner.shutdown()
        for s in (self.fix_sock, self.truth_sock):
            if s is not None:
                s.close(0)
        if self.sock is not None:
            self.sock.close(0)

    def _watch_code(self) -> None:
        """Keep the sandbox's descriptor in the poller (a respawned sandbox has a new one)."""
        fd = self.code.fileno()
        flags = zmq.POLLIN | (zmq.POLLOUT if self.code.wants_write() else 0)
        if fd != self._code_fd:
            if self._code_fd is not None:
                try:
                    self.poller.unregister(self._code_fd)
                except KeyError:
                    pass
            self._code_fd = fd
        if fd is not None:
            self.poller.register(fd, flags)  # registering again updates the flags

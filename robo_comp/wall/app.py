"""The wall's loop: one poller over the event feed (and a shared view feed), a frame clock, no threads.

Each :meth:`WallApp.step` waits on the SUB sockets until the next frame is due, applies every
event that arrived, handles the window's input, carries out commands (``give`` through the
core: ownership is the core's to enforce, a refusal lands on the message bar), refreshes the
open monitor boxes once a second, draws and flips.

A wall only reads the public feed and asks for a snapshot, so it can start and stop at any
time without disturbing the match, and any number of walls may run at once (thesis 3.8).
"""
from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pygame
import zmq

from robo_comp.client import Client, recv_event
from robo_comp import protocol as P
from robo_comp.errors import AuthError, FieldError, RoboCompError
from robo_comp.wall.interact import Command, Interaction
from robo_comp.view.model import MatchView, Thing
from robo_comp.view.story import Story
from robo_comp.wall.render import Overlay, Renderer
from robo_comp.wall.replay import ReplaySource
from robo_comp.wall.view import TileSpec, ViewState
from robo_comp.world.mapservice import unpack_costs
from robo_comp.world.video import decode_webm

MONITOR_REFRESH = 1.0
VIEW_REPUBLISH = 1.0
DRAIN_BUDGET = 50_000
_KEYS = {pygame.K_RETURN: "enter", pygame.K_KP_ENTER: "enter", pygame.K_ESCAPE: "escape",
         pygame.K_PLUS: "+", pygame.K_EQUALS: "+", pygame.K_KP_PLUS: "+", pygame.K_MINUS: "-",
         pygame.K_KP_MINUS: "-", pygame.K_0: "0", pygame.K_LEFT: "left", pygame.K_RIGHT: "right",
         pygame.K_UP: "up", pygame.K_DOWN: "down"}
#: Seconds a replay seeks back or on with [ and ].
SEEK_STEP = 10.0


class LiveSource:
    """The core's public event feed plus a session for snapshot, monitor, pictures and commands."""

    def __init__(self, core: str, token: str, *, timeout: float = 3.0, curve_cert: str | None = None,
                 core_key: str | None = None) -> None:
        # both sockets (the session and the event feed) use the client's CurveZMQ keys, if any
        self.client = Client(core, token, client="wall", timeout=timeout, curve_cert=curve_cert, core_key=core_key)
        self.sub = self.client.subscribe()
        #: The ticker's lines and the victims revealed at the finish, told from the events this
        #: wall received (on its own timeline: seconds since it started, as the web gateway's).
        self.story = Story()
        self.t0 = time.monotonic()

    def start(self, model: MatchView) -> None:
        """Subscribe first, then take the snapshot, so no event after it is missed."""
        self.sub.poll(200)  # let the subscription reach the PUB socket (ZeroMQ's slow joiner)
        while self.sub.poll(0):
            self.sub.recv_multipart()  # older than the snapshot
        model.load_snapshot(self.request(self.client.snapshot))
        try:  # cell costs for the shading, if this core has the map service
            model.set_costs(unpack_costs(self.request(self.client.request, "map")["costs"]))
        except (RoboCompError, KeyError, TypeError, ValueError):
            pass

    def find(self, fid: Any) -> dict[str, Any] | None:
        """The full record of find ``fid`` if this token may see it (its team's; all for the referee)."""
        for f in self.request(self.client.snapshot).get("finds") or []:
            if f.get("id") == fid:
                return f
        return None

    def drain(self, model: MatchView, budget: int = DRAIN_BUDGET) -> int:
        """Apply every waiting event (at most ``budget``); return how many."""
        n = 0
        while n < budget:
            try:
                topic, payload = recv_event_nowait(self.sub)
            except zmq.Again:
                break
            model.apply(topic, payload)
            self.story.follow(model, topic, payload, time.monotonic() - self.t0)
            n += 1
        return n

    def request(self, fn: Callable[..., Any], *args: Any, **kw: Any) -> Any:
        """Call a client method; say hello again once if the core forgot this idle session."""
        try:
            return fn(*args, **kw)
        except AuthError:
            self.client.connect()
            return fn(*args, **kw)

    def picture(self, pid: int) -> bytes:
        """PNG bytes of picture ``pid`` (the core checks the token may see it)."""
        return self.request(self.client.request, "picture.get", id=pid)["png"]

    def video(self, vid: int) -> bytes:
        """WebM bytes of video ``vid`` (the core checks the token may see it)."""
        return self.request(self.client.request, "video.get", id=vid)["webm"]

    def close(self) -> None:
        """Leave the core (the match goes on)."""
        self.sub.close(0)
        self.client.close()


def recv_event_nowait(sub: zmq.Socket) -> tuple[str, dict[str, Any]]:
    """Like :func:`robo_comp.client.recv_event` but raises ``zmq.Again`` when nothing waits."""
    if not sub.poll(0):
        raise zmq.Again()
    return recv_event(sub)


class WallApp:
    """One wall process: a tile of the canvas, a model, a source (live or replay) and the window."""

    def __init__(self, model: MatchView, tile: TileSpec, view: ViewState | None = None, *,
                 source: LiveSource | ReplaySource | None = None, fps: float = 30.0, trails: bool = True,
                 double_click: float = 0.4, path_wait: float = 1.0, view_pub: str | None = None,
                 view_sub: str | None = None, clock: Callable[[], float] = time.monotonic) -> None:
        self.model = model
        self.tile = tile
        self.view = view or ViewState()
        self.source = source
        self.fps = fps
        self.clock = clock
        self.renderer = Renderer(model, tile, self.view, trails=trails)
        self.interaction = Interaction(model, self.view, self.renderer.layout, self.renderer.geometry,
                                       self.renderer.panel_boxes, self.renderer.robot_radius,
                                       double_click=double_click, path_wait=path_wait)
        self.monitor_data: dict[int, dict[str, Any] | str] = {}
        self.pictures: dict[int, bytes | str] = {}
        #: Video id -> its frames, or why not (fetched when its info box opens).
        self.videos: dict[int, list[Any] | str] = {}
        self.screen: pygame.Surface | None = None
        self.running = True
        self.frames = 0
        self._next_frame = 0.0
        self._monitor_at = 0.0
        self._monitor_asks: dict[int, tuple[int, float]] = {}  # tag -> (request id, sent at)
        self._view_sent: tuple[Any, float] = (None, 0.0)
        self._ctx: zmq.Context = zmq.Context.instance()
        self.view_pub = self.view_sub = None
        self.view_pub_url = ""
        if view_pub:
            self.view_pub = self._ctx.socket(zmq.PUB)
            self.view_pub.setsockopt(zmq.LINGER, 0)
            try:
                self.view_pub.bind(view_pub)  # "tcp://*:0"-style wildcards work: see view_pub_url
            except zmq.ZMQError as e:
                self.view_pub.close(0)
                raise FieldError(f"--view-pub {view_pub}: cannot publish the view there ({e.strerror}); "
                                 "is another wall using that port?") from None
            self.view_pub_url = self.view_pub.getsockopt_string(zmq.LAST_ENDPOINT)
        if view_sub:
            self.view_sub = self._ctx.socket(zmq.SUB)
            self.view_sub.setsockopt(zmq.LINGER, 0)
            self.view_sub.setsockopt(zmq.SUBSCRIBE, b"")
            self.view_sub.connect(view_sub)
        self.poller = zmq.Poller()
        for s in (getattr(source, "sub", None), self.view_sub):
            if s is not None:
                self.poller.register(s, zmq.POLLIN)

    # ------------------------------------------------------------------ window
    def open_window(self, *, fullscreen: bool = False, title: str = "robo_comp wall") -> pygame.Surface:
        """Open the window (the SDL dummy driver gives an invisible one for tests)."""
        pygame.display.init()
        pygame.font.init()
        flags = pygame.FULLSCREEN if fullscreen else 0
        self.screen = pygame.display.set_mode(self.tile.size, flags)
        c, r = self.tile.col, self.tile.row
        pygame.display.set_caption(title if self.tile.cols * self.tile.rows == 1 else f"{title} tile {c},{r}")
        return self.screen

    def overlay(self) -> Overlay:
        """The user's state for the renderer."""
        info = self.model.things.get(self.view.info) if self.view.info else None
        src = self.source
        return Overlay(self.interaction.selected, list(self.interaction.points),
                       {t: self.monitor_data[t] for t in self.view.monitors if t in self.monitor_data},
                       info, self.pictures, self.interaction.hint(), self.videos,
                       story=src.story if src is not None else None,
                       story_now=src.replay_time() if isinstance(src, ReplaySource) else None)

    def render(self, surf: pygame.Surface, now: float | None = None) -> None:
        """Draw the current state onto ``surf``."""
        self.renderer.draw(surf, now, self.overlay())

    def screenshot(self, path: str | Path) -> Path:
        """Render one frame off-screen and save it as PNG (the clock as last heard)."""
        surf = pygame.Surface(self.tile.size, 0, 32)
        self.render(surf, None)
        pygame.image.save(surf, str(path))
        return Path(path)

    # ------------------------------------------------------------------ the loop
    def run(self, *, max_frames: int = 0) -> int:
        """Step until the window closes (or ``max_frames`` frames); return the frame count."""
        while self.running and (not max_frames or self.frames < max_frames):
            self.step()
        return self.frames

    def step(self, wait: bool = True) -> None:
        """One frame: wait for events until it is due, apply them, handle input, draw, flip."""
        while wait:  # take in events as they come until the frame is due
            left = self._next_frame - self.clock()
            if left <= 0:
                break
            if not self.poller.sockets:
                time.sleep(left)
            elif self.poller.poll(int(left * 1000)):
                self.pump()
        self.pump()
        now = self.clock()
        self._next_frame = max(self._next_frame + 1.0 / self.fps, now) if self.fps else now
        if pygame.display.get_init():
            for ev in pygame.event.get():
                self.handle(ev, now)
        for cmd in self.interaction.tick(now):
            self.execute(cmd)
        self.refresh(now)
        self.publish_view(now)
        if self.screen is not None:
            self.renderer.draw(self.screen, self.model.clock(), self.overlay(), incremental=True)
            pygame.display.flip()
        self.frames += 1

    def pump(self) -> None:
        """Apply what the sources have: events, replay records and a master tile's view."""
        if isinstance(self.source, LiveSource):
            self.source.drain(self.model)
        elif isinstance(self.source, ReplaySource):
            self.source.advance(self.model)
        if self.view_sub is not None:
            while self.view_sub.poll(0):
                self.view.update(P.unpack(self.view_sub.recv()))

    def handle(self, ev: pygame.event.Event, now: float) -> None:
        """One pygame event: mouse presses, wheel, keys, window close."""
        ox, oy = self.tile.origin
        cmds: list[Command] = []
        if ev.type == pygame.QUIT:
            self.running = False
        elif ev.type == pygame.MOUSEBUTTONDOWN and ev.button in (1, 3):
            cmds = self.interaction.click(ev.pos[0] + ox, ev.pos[1] + oy, ev.button, now)
        elif ev.type == pygame.MOUSEWHEEL:
            self.interaction.zoom(1.25 if ev.y > 0 else 0.8)
        elif ev.type == pygame.KEYDOWN:
            if ev.key == pygame.K_q:
                self.running = False
            elif isinstance(self.source, ReplaySource) and self.replay_key(ev):
                pass
            elif ev.key in _KEYS:
                cmds = self.interaction.key(_KEYS[ev.key], now)
            elif getattr(ev, "unicode", "") in ("+", "-", "d", "D", "l"):
                cmds = self.interaction.key(ev.unicode, now)
        for cmd in cmds:
            self.execute(cmd)

    def replay_key(self, ev: pygame.event.Event) -> bool:
        """A replay's keys: ``[`` / ``]`` seek 10 s back / on, Home / End to the start / the
        end, space pauses and plays; True when ``ev`` was one of them."""
        src = self.source
        assert isinstance(src, ReplaySource)
        char = getattr(ev, "unicode", "")
        if char in ("[", "]"):
            src.jump(self.model, src.replay_time() + (SEEK_STEP if char == "]" else -SEEK_STEP))
        elif ev.key in (pygame.K_HOME, pygame.K_END):
            src.jump(self.model, 0.0 if ev.key == pygame.K_HOME else src.duration)
        elif ev.key == pygame.K_SPACE:
            src.toggle_pause()
        else:
            return False
        return True

    # ------------------------------------------------------------------ commands
    def execute(self, cmd: Command) -> None:
        """Carry out a command; refusals by the core go to the message bar."""
        if cmd.kind == "monitor" and cmd.tag is not None:
            if cmd.tag not in self.view.monitors:
                self.view.monitors.append(cmd.tag)
            self._monitor_at = 0.0
        elif cmd.kind == "info":
            self.view.info = cmd.key
            self._fetch_details()
            self._fetch_pictures()
        elif cmd.kind == "close":
            if cmd.key == "info":
                self.view.info = None
            elif isinstance(cmd.key, tuple) and cmd.key[0] == "monitor":
                self.view.monitors = [t for t in self.view.monitors if t != cmd.key[1]]
                self.monitor_data.pop(cmd.key[1], None)
        elif cmd.kind == "give" and cmd.tag is not None:
            self.give(cmd.tag, cmd.task, cmd.args)

    def give(self, tag: int, task: str, args: list[Any]) -> None:
        """Send a task through the core; the core decides whether this token may command ``tag``."""
        if not isinstance(self.source, LiveSource):
            self.model.note(f"robot {tag}: {task} not sent: a replay cannot command robots", "error")
            return
        try:
            reply = self.source.request(self.source.client.give, tag, task, args)
        except RoboCompError as e:
            self.model.note(f"refused: {task} for robot {tag}: {e.message}", "error")
            return
        self.model.note(f"robot {tag}: {task} {args} given (task {reply.get('task_id')})")

    def refresh(self, now: float) -> None:
        """Ask for the open monitors' data (once a second) and take the answers that came.

        A live core is asked without waiting: a slow core delays the monitor boxes, never a
        frame (an answer that takes longer than the client's timeout is given up)."""
        if isinstance(self.source, LiveSource):
            self._take_monitor_answers(now)
        if not self.view.monitors or now - self._monitor_at < MONITOR_REFRESH:
            return
        self._monitor_at = now
        for tag in list(self.view.monitors):
            if isinstance(self.source, LiveSource):
                if tag not in self._monitor_asks:
                    self._monitor_asks[tag] = (self.source.client.ask("monitor", tag=tag), now)
            else:
                r = self.model.robots.get(tag)
                self.monitor_data[tag] = ({"tag": tag, "team": r.team, "status": r.status, "x": r.x, "y": r.y,
                                           "heading": r.heading, "task": None, "queue": 0}
                                          if r else "not in this replay")
        if self.view.info:
            self._fetch_pictures()

    def _take_monitor_answers(self, now: float) -> None:
        assert isinstance(self.source, LiveSource)
        client = self.source.client
        for tag, (rid, sent) in list(self._monitor_asks.items()):
            data: dict[str, Any] | str | None
            try:
                data = client.answer(rid)
            except AuthError:  # the core forgot this idle session: say hello again, ask anew
                self._monitor_asks.clear()
                client.connect()
                return
            except RoboCompError as e:
                data = f"refused: {e.message}"
            if data is None:
                if now - sent < client.timeout:
                    continue
                client.forget(rid)
                data = f"no answer from the core within {client.timeout:.0f} s"
            del self._monitor_asks[tag]
            if tag in self.view.monitors:
                self.monitor_data[tag] = data

    def _fetch_details(self) -> None:
        """A find's evidence and verdict are not public: ask the core what this token may know."""
        thing = self.model.things.get(self.view.info or "")
        if thing is None or thing.kind != "find" or not isinstance(self.source, LiveSource):
            return
        try:
            record = self.source.find(thing.id)
        except RoboCompError as e:
            self.model.note(f"refused: details of find {thing.id}: {e.message}", "error")
            return
        if record is not None:
            self.model.merge_find(record)
        else:
            thing.info.setdefault("evidence", "not visible to this token")

    def _fetch_pictures(self) -> None:
        thing = self.model.things.get(self.view.info or "")
        if thing is None:
            return
        for pid in thing.pictures()[:4]:
            if pid in self.pictures:
                continue
            try:
                if self.source is not None:
                    self.pictures[pid] = self.source.picture(pid)
            except RoboCompError as e:
                self.pictures[pid] = e.message
        self._fetch_videos(thing)

    def _fetch_videos(self, thing: Thing) -> None:
        """The frames of the thing's video (once), for the info box to play."""
        for vid in thing.videos():
            if vid in self.videos or self.source is None:
                continue
            try:
                self.videos[vid] = decode_webm(self.source.video(vid))
            except RoboCompError as e:
                self.videos[vid] = e.message

    def publish_view(self, now: float) -> None:
        """A master tile sends its view when it changes and every second (for late joiners)."""
        if self.view_pub is None:
            return
        state = self.view.to_dict()
        if state != self._view_sent[0] or now - self._view_sent[1] >= VIEW_REPUBLISH:
            self.view_pub.send(P.pack(state))
            self._view_sent = (state, now)

    def close(self) -> None:
        """Close sockets and the window."""
        if self.source is not None and hasattr(self.source, "close"):
            self.source.close()
        for s in (self.view_pub, self.view_sub):
            if s is not None:
                s.close(0)
        if self.screen is not None:
            pygame.display.quit()
            self.screen = None

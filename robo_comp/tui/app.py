"""What the team console and the referee console share: the link, the model, STOP, toasts.

:class:`ConsoleApp` owns a :class:`~robo_comp.link.CoreLink` (or any object with
the same few methods: the snapshot tests pass a canned one) and a
:class:`~robo_comp.tui.model.ConsoleModel`. The link posts :class:`CoreEvent` and
:class:`LinkChanged` messages; the app folds events into the model, raises toasts for what
matters, and lets the screen redraw a few times a second. Every request runs in a worker and
every refusal becomes a readable notification, never a traceback.
"""
from __future__ import annotations

import logging

from collections import deque
from collections.abc import Callable, Iterable
from functools import partial
from typing import Any, Protocol

from textual.app import App, SystemCommand
from textual.binding import Binding
from textual.command import DiscoveryHit, Hit, Hits, Provider
from textual.css.query import NoMatches
from textual.screen import Screen

from robo_comp.errors import RoboCompError
from robo_comp.link import CoreLink, EventSink, LinkState, StateSink
from robo_comp.tui.messages import CoreEvent, LinkChanged
from robo_comp.tui.model import OUTAGE_WORDS, ConsoleModel, LogEntry

#: Notification titles by error code (the message itself comes from the core).
ERROR_TITLES = {
    "E_PHASE": "Not now", "E_BAD_TASK": "Task refused", "E_UNAVAILABLE": "Robot unavailable",
    "E_NOT_YOURS": "Not your robot", "E_FORBIDDEN": "Not allowed", "E_UPLOAD": "Upload refused",
    "E_TIMEOUT": "No answer", "E_CONNECTION": "Not connected", "E_AUTH": "Token refused",
    "E_FIELD": "Refused", "E_RATE": "Too fast", "E_UNKNOWN_TYPE": "Not on this core",
}
#: Requests a console may lack on an older core, by role; a core without them shows them greyed out.
OPTIONAL_REQUESTS = {"team": ("upload", "score"),
                     "referee": ("upload", "approve", "score", "penalty", "disqualify", "broadcast", "match")}


log = logging.getLogger("robo_comp.tui")
#: What a student sees when the console itself fails (the details go to the log, never a traceback).
INTERNAL_PROBLEM = "the console hit a problem of its own (details in {log}); the match and your robots are not affected"


def log_place() -> str:
    """Where this process's log goes: the file ``robo-comp team``/``referee`` opened, if any."""
    for h in logging.getLogger().handlers:
        if isinstance(h, logging.FileHandler):
            return h.baseFilename
    return "the error output of the terminal it was started from"

class Link(Protocol):
    """What a console needs from its link to the core (:class:`CoreLink` or a stand-in)."""

    state: LinkState
    on_event: EventSink  # the console sets both to its own sinks
    on_state: StateSink

    @property
    def info(self) -> dict[str, Any]:
        """The core's hello reply."""

    def start(self) -> None: ...
    async def close(self) -> None: ...
    async def request(self, type_: str, **body: Any) -> dict[str, Any]: ...
    async def available(self, type_: str) -> bool: ...


class RobotCommands(Provider):
    """Command palette: per-robot commands (select, give a task, stop, …) for every robot."""

    def _commands(self) -> list[tuple[str, str, Callable[[], Any]]]:
        app = self.app
        assert isinstance(app, ConsoleApp)
        out: list[tuple[str, str, Callable[[], Any]]] = []
        for tag in sorted(app.model.robots):
            out += [(f"Stop robot {tag}", "halt it at once; its tasks are cancelled", partial(app.stop_robot, tag)),
                    (f"Select robot {tag}", "show its monitor data", partial(app.select_robot, tag))]
            out += app.robot_commands(tag)
        return out

    async def discover(self) -> Hits:
        for title, help_, cb in self._commands():
            yield DiscoveryHit(title, cb, help=help_)

    async def search(self, query: str) -> Hits:
        matcher = self.matcher(query)
        for title, help_, cb in self._commands():
            score = matcher.match(title)
            if score > 0:
                yield Hit(score, matcher.highlight(title), cb, help=help_)


class ConsoleApp(App[None]):
    """Base of :class:`~robo_comp.tui.team_app.TeamApp` and :class:`~robo_comp.tui.referee_app.RefereeApp`."""

    CSS_PATH = "console.tcss"
    COMMANDS = App.COMMANDS | {RobotCommands}
    BINDINGS = [
        Binding("ctrl+s", "stop", "STOP", priority=True, tooltip="Halt the selected robot at once"),
        Binding("ctrl+x", "stop_all", "STOP ALL", priority=True, tooltip="Halt every robot you may command"),
    ]
    NOTIFICATION_TIMEOUT = 6
    CLIENT_NAME = "console"

    def __init__(self, core: str = "", token: str = "", *, link: Link | None = None,
                 clock: Callable[[], float] | None = None, wall_clock: Callable[[], float] | None = None,
                 poll: bool = True, curve_cert: str | None = None, core_key: str | None = None) -> None:
        super().__init__()
        self.model = ConsoleModel()
        if clock is not None:
            self.model.clock = clock
        if wall_clock is not None:
            self.model.wall_clock = wall_clock
        self.link: Link = link or CoreLink(core, token, client=self.CLIENT_NAME, on_event=self._post_event,
                                           on_state=self._post_state, curve_cert=curve_cert, core_key=core_key)
        if link is not None:
            link.on_event = self._post_event
            link.on_state = self._post_state
        #: What the core serves (request type -> True/False), as far as the console found out.
        #: Not ``features``: Textual's App keeps its own flags (``TEXTUAL=debug,devtools``) there.
        self.core_features: dict[str, bool] = {}
        self.selected: int | None = None
        self.poll = poll
        self._drawn = -1
        self._was_connected = False
        self._warned_lost = False
        self._probing: set[str] = set()
        self.link_state = "connecting"
        self._last_refusal = ""
        #: Every notification raised, newest last (tests read it; toasts vanish after a while).
        self.notices: deque[str] = deque(maxlen=500)

    def notify(self, message: str, *, title: str = "", severity: Any = "information",
               timeout: float | None = None, markup: bool = False) -> None:
        """Raise a toast (markup off: core messages may hold brackets) and keep it in :attr:`notices`."""
        self.notices.append(f"{title}: {message}" if title else message)
        super().notify(message, title=title, severity=severity, timeout=timeout, markup=markup)

    # ------------------------------------------------------------------ wiring
    def _post_event(self, topic: str, team: str | None, data: dict[str, Any]) -> None:
        self.post_message(CoreEvent(topic, team, data))

    def _post_state(self, state: LinkState, detail: str, info: dict[str, Any]) -> None:
        self.post_message(LinkChanged(state, detail, info))

    def main_screen(self) -> Screen[Any]:
        """The console's main screen (subclasses)."""
        raise NotImplementedError

    def on_mount(self) -> None:
        self.push_screen(self.main_screen())
        self.set_interval(0.25, self._redraw)
        if self.poll:
            self.set_interval(1.0, self._poll)
        self.link.start()

    async def on_unmount(self) -> None:
        await self.link.close()

    def main(self) -> Any:
        """The main screen once it is composed (None before, and while the app closes)."""
        screen = self.screen_stack[1] if len(self.screen_stack) > 1 else None
        return screen if screen is not None and getattr(screen, "ready", False) else None

    def _redraw(self, force: bool = False) -> None:
        screen = self.main()
        if screen is not None and (force or self.model.version != self._drawn):
            self._drawn = self.model.version
            try:
                screen.refresh_views()
            except NoMatches:  # the app is closing: the screen's widgets went before the screen
                pass

    # ------------------------------------------------------------------ link state
    async def on_link_changed(self, msg: LinkChanged) -> None:
        self.link_state = msg.state.value
        if self.main() is not None:
            self.main().query_one("MatchBar").link = msg.state.value
        if msg.state is LinkState.CONNECTED:
            self.model.role, self.model.team = msg.info.get("role", ""), msg.info.get("team")
            if self._was_connected:
                self.notify("Reconnected to the core; the view is up to date again.", title="Reconnected")
            self._was_connected = True
            self.connected(msg.info)
            self._warned_lost = False
            self.sub_title = "connected"
            self.spawn(self.reload, group="reload", exclusive=True)
        elif msg.state is LinkState.RECONNECTING:
            self.sub_title = "reconnecting…"
            if not self._warned_lost:
                self._warned_lost = True
                self.notify("Lost the core; reconnecting… (robots halt on their own meanwhile)",
                            title="Reconnecting", severity="warning", timeout=10)
        elif msg.state is LinkState.CLOSED and msg.detail not in ("closed", "", self._last_refusal):
            self._last_refusal = msg.detail
            self.notify(msg.detail, title="Cannot connect", severity="error", timeout=10)

    def connected(self, info: dict[str, Any]) -> None:
        """Hook: the hello reply arrived (subclasses; Textual calls message handlers of every class
        in the MRO, so subclasses extend this instead of ``on_link_changed``)."""

    async def reload(self) -> None:
        """Fetch everything after (re)connecting: snapshot, scores, features, selected robot."""
        snap = await self.call("snapshot")
        if snap is None:
            return
        self.model.load_snapshot(snap)
        await self.detect_features()
        if self.core_features.get("score"):
            score = await self.call("score", quiet=True)
            if score:
                self.model.set_scores(score.get("teams") or [])
                self.model.set_match(score)
        self.refresh_bindings()
        if self.selected is None and self.model.robots:
            self.select_robot(min(self.model.robots))
        elif self.selected is not None:
            await self.fetch_detail(self.selected)
        self._redraw(force=True)

    async def detect_features(self) -> None:
        """Which optional requests this core serves: from the hello's ``requests`` list when the
        core sends one, else by probing (an ``E_UNKNOWN_TYPE`` answer means "not here yet")."""
        known = self.link.info.get("requests")
        names = OPTIONAL_REQUESTS.get(self.model.role, ())
        if isinstance(known, list):
            self.core_features.update({n: n in known for n in names})
            return
        for name in names:
            self._probing.add(name)
            try:
                self.core_features[name] = await self.link.available(name)
            except RoboCompError:
                self.core_features[name] = False

    def _own_probe(self, topic: str, data: dict[str, Any]) -> bool:
        """Is this ``refused`` event the echo of our own feature probe (an empty request)?"""
        if topic != "refused" or not self._probing or data.get("by") != (self.link.info.get("team") or "referee"):
            return False
        if data.get("code") not in ("E_UNKNOWN_TYPE", "E_FIELD"):
            return False
        msg = str(data.get("message", ""))
        return data.get("type") in self._probing or any(f"'{n}'" in msg for n in self._probing)

    async def _poll(self) -> None:
        """Once a second: correct the robots table and refresh the selected robot's monitor data."""
        if getattr(self.link, "state", None) is not LinkState.CONNECTED:
            return
        rows = await self.call("robots", quiet=True)
        if rows is not None:
            self.model.set_robots(rows.get("robots") or [])
        if self.selected is not None and self.selected in self.model.robots:
            await self.fetch_detail(self.selected)

    # ------------------------------------------------------------------ requests
    def spawn(self, work: Any, group: str = "default", exclusive: bool = False) -> None:
        """Run a coroutine (or async callable) as a worker; a failure is a notification, never a crash."""
        self.run_worker(work, group=group, exclusive=exclusive, exit_on_error=False)

    def on_worker_state_changed(self, event: Any) -> None:
        from textual.worker import WorkerState

        if event.state is WorkerState.ERROR and self.main() is not None:
            log.error("console task failed", exc_info=event.worker.error)
            self.notify(INTERNAL_PROBLEM.format(log=log_place()), title="Console error", severity="error")

    async def call(self, type_: str, *, quiet: bool = False, title: str | None = None,
                   **body: Any) -> dict[str, Any] | None:
        """Send a request; on refusal show the core's sentence as a notification and return None."""
        try:
            return await self.link.request(type_, **body)
        except RoboCompError as e:
            if e.code == "E_UNKNOWN_TYPE":
                self.core_features[type_] = False
                self.refresh_bindings()
                if not quiet:
                    self.notify(f"this core does not offer '{type_}' yet", title="Not available", severity="warning")
                return None
            if not quiet:
                self.notify(e.message, title=title or ERROR_TITLES.get(e.code, "Refused"), severity="error",
                            timeout=8)
            return None
        except Exception:  # never a traceback on screen
            log.exception("request %r failed in the console", type_)
            if not quiet:
                self.notify(INTERNAL_PROBLEM.format(log=log_place()), title="Unexpected error", severity="error", timeout=8)
            return None

    async def fetch_detail(self, tag: int) -> None:
        """Fetch robot ``tag``'s monitor data into the model."""
        d = await self.call("monitor", tag=tag, quiet=True)
        if d is not None:
            self.model.set_detail(tag, d)

    # ------------------------------------------------------------------ events
    def on_core_event(self, msg: CoreEvent) -> None:
        if self._own_probe(msg.topic, msg.data):
            return
        entry = self.model.apply(msg.topic, msg.team, msg.data)
        screen = self.main()
        if entry is not None and screen is not None:
            screen.log_entry(entry)
        if entry is not None:
            self.toast(entry)

    def toast(self, e: LogEntry) -> None:
        """A notification for the events that matter to a person at the console."""
        d = e.data
        t = e.topic
        if self.model.role == "referee" and t in ("task.done", "robot.returned", "robot.stopped"):
            return  # the referee watches every team: only what needs the referee is a toast
        if t == "task.done" and d.get("state") != "cancelled":
            ok = bool(d.get("ok"))
            self.notify(f"{d.get('name')} #{d.get('task_id')}: {d.get('status', '')}",
                        title=f"Robot {d.get('tag')} {'finished' if ok else 'failed'}",
                        severity="information" if ok else "warning")
        elif t == "robot.lost":
            self.notify(str(d.get("message", "no reports")), title=f"Robot {d.get('tag')} is lost",
                        severity="error", timeout=10)
        elif t == "robot.returned":
            self.notify(f"robot {d.get('tag')} is connected again", title="Robot back")
        elif t == "robot.stopped":
            self.notify(f"halted in {d.get('ms', 0):.0f} ms; {len(d.get('cancelled') or [])} task(s) cancelled",
                        title=f"Robot {d.get('tag')} stopped", severity="warning")
        elif t == "match.phase" and d.get("action") == "outage":
            self.notify(f"a core outage now {OUTAGE_WORDS.get(str(d.get('outage')), '?')} (by {d.get('by', 'the referee')})",
                        title="Outage rule")
        elif t == "match.phase":
            self.notify(f"by {d.get('by', 'the referee')}", title=f"Match {str(d.get('phase', '?')).upper()}",
                        severity="warning" if d.get("phase") != "running" else "information")
        elif t == "broadcast":
            self.notify(str(d.get("message", "")), title="Referee", severity="warning", timeout=15)
        elif t == "penalty":
            self.notify(f"{d.get('points')} points: {d.get('reason', '')}", title=f"Penalty for {d.get('team')}",
                        severity="error", timeout=10)
        elif t == "disqualified":
            self.notify(str(d.get("reason", "")), title="Disqualified", severity="error", timeout=15)
        elif t == "upload.done":
            self.notify(str(d.get("message", "")), title=f"Upload {'accepted' if d.get('ok') else 'refused'}",
                        severity="information" if d.get("ok") else "error")
        elif t == "score.change" and self.model.role == "team" and d.get("points"):
            self.notify(str(d.get("reason", "")), title=f"{d.get('points', 0):+g} points",
                        severity="information" if d.get("points", 0) > 0 else "warning")
        elif t == "upload.pending" and self.model.role == "referee":
            self.notify(f"{d.get('team')}: {d.get('filename')} (press a to approve)", title="Upload waits")

    # ------------------------------------------------------------------ selection and STOP
    def select_robot(self, tag: int | None) -> None:
        """Make ``tag`` the selected robot (monitor, map, STOP)."""
        changed = tag != self.selected
        self.selected = tag
        screen = self.main()
        if screen is not None:
            screen.robot_selected(tag)
        if changed and tag is not None:
            self.spawn(partial(self.fetch_detail, tag), group=f"detail-{tag}", exclusive=True)

    def stop_robot(self, tag: int) -> None:
        """Send STOP for robot ``tag`` at once (never waits behind other requests)."""
        self.spawn(self._stop(tag), group="stop")

    async def _stop(self, tag: int) -> None:
        reply = await self.call("stop", tag=tag, title=f"Robot {tag} did not stop")
        if reply is not None:
            self.model.apply("robot.stopped", self.model.team, {"tag": tag, "x": reply.get("x"), "y": reply.get("y"),
                                                                "cancelled": reply.get("cancelled") or [],
                                                                "ms": reply.get("ms", 0)})

    def action_stop(self) -> None:
        """STOP the selected robot."""
        if self.selected is None:
            self.notify("select a robot first", title="STOP", severity="warning")
            return
        self.stop_robot(self.selected)

    def action_stop_all(self) -> None:
        """STOP every robot this console may command."""
        tags = [t for t, r in self.model.robots.items() if r.get("status") == "connected"]
        if not tags:
            self.notify("no connected robot to stop", title="STOP ALL", severity="warning")
        for tag in tags:
            self.stop_robot(tag)

    # ------------------------------------------------------------------ palette
    def robot_commands(self, tag: int) -> list[tuple[str, str, Callable[[], Any]]]:
        """Extra per-robot palette commands (subclasses)."""
        return []

    def console_commands(self) -> Iterable[tuple[str, str, Callable[[], Any]]]:
        """Console actions listed in the command palette (subclasses add theirs)."""
        yield "STOP selected robot", "halt it at once (ctrl+s)", self.action_stop
        yield "STOP ALL robots", "halt every robot (ctrl+x)", self.action_stop_all

    def get_system_commands(self, screen: Screen[Any]) -> Iterable[SystemCommand]:
        yield from super().get_system_commands(screen)
        for title, help_, cb in self.console_commands():
            yield SystemCommand(title, help_, cb)

    def feature(self, name: str) -> bool | None:
        """``check_action`` helper: None (greyed out) when the core lacks request ``name``."""
        return None if self.core_features.get(name) is False else True


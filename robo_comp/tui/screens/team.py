"""The team console's main screen: robots, monitor, map and events of one team, live."""
from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

from textual import events
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import Screen
from textual.widgets import Footer

from robo_comp.tui.app import ConsoleApp
from robo_comp.tui.messages import RobotSelected
from robo_comp.tui.model import ConsoleModel, LogEntry
from robo_comp.tui.widgets.event_log import EventLog
from robo_comp.tui.widgets.map_view import MapView
from robo_comp.tui.widgets.monitor import MonitorPanel
from robo_comp.tui.widgets.robots_table import RobotsTable
from robo_comp.tui.widgets.score import MatchBar

#: Below this width the panels stack and ``v`` switches between monitor, map and events.
NARROW = 120
PANELS = ("monitor", "map", "log")


@runtime_checkable
class GivesTasks(Protocol):
    """A console with a give-task form (the team console: it imports this module, so it is not
    named here)."""

    def action_give_task(self, task: str | None = None) -> None:
        """Open the give-task form for the selected robot."""


class ConsoleScreen(Screen[None]):
    """Shared behaviour of the main screens: narrow layout, selection, redraw, logging."""

    def __init__(self, model: ConsoleModel) -> None:
        super().__init__()
        self.model = model
        self.panel = "monitor"
        #: True once composed and mounted (the app draws only then).
        self.ready = False

    @property
    def console_app(self) -> ConsoleApp:
        """The console this screen belongs to (Textual types ``self.app`` as any App)."""
        app = self.app
        assert isinstance(app, ConsoleApp), "a console screen is pushed by a console"
        return app

    def on_resize(self, event: events.Resize) -> None:
        self._narrow(event.size.width < NARROW)

    def _narrow(self, narrow: bool) -> None:
        self.set_class(narrow, "-narrow")
        for panel in self.query("#monitor, #map, #log"):
            panel.border_subtitle = "v ▸ next panel" if narrow else ""

    def on_mount(self) -> None:
        self._narrow(self.app.size.width < NARROW)
        self.add_class(f"-panel-{self.panel}")
        self.ready = True
        app = self.console_app
        app.connected(app.link.info)
        self.query_one(MatchBar).link = app.link_state
        app.call_later(app._redraw, True)

    def on_unmount(self) -> None:
        self.ready = False

    def action_view(self) -> None:
        """Narrow terminals: show the next panel (monitor → map → events)."""
        self.remove_class(f"-panel-{self.panel}")
        self.panel = PANELS[(PANELS.index(self.panel) + 1) % len(PANELS)]
        self.add_class(f"-panel-{self.panel}")
        self.notify(f"showing the {'event log' if self.panel == 'log' else self.panel}", timeout=1.5)

    def on_robot_selected(self, msg: RobotSelected) -> None:
        self.console_app.select_robot(msg.tag)

    def robot_selected(self, tag: int | None) -> None:
        """The app's selection changed: show it."""
        self.query_one(MonitorPanel).show(self.model, tag)
        m = self.query_one(MapView)
        m.selected = tag
        m.update_map()
        table = self.query_one(RobotsTable)
        if tag is not None and table.selected_tag != tag:
            table.select_tag(tag)

    def refresh_views(self) -> None:
        """Redraw everything from the model."""
        self.query_one(RobotsTable).update_from(self.model)
        self.query_one(MonitorPanel).show(self.model, self.console_app.selected)
        self.query_one(MapView).update_map()
        self.query_one(MatchBar).refresh()

    def log_entry(self, entry: LogEntry) -> None:
        """Append an event to the log pane."""
        self.query_one(EventLog).add(entry)


class TeamScreen(ConsoleScreen):
    """Robots table, monitor panel, map and event log of one team."""

    BINDINGS = [
        Binding("t", "app.give_task", "Task", tooltip="Give the selected robot a task"),
        Binding("u", "app.upload", "Upload", tooltip="Upload an extension or code"),
        Binding("v", "view", "View", tooltip="Narrow terminals: switch monitor / map / events"),
        Binding("s", "app.stop", "STOP", show=False),
    ]

    def __init__(self, model: ConsoleModel, team: str) -> None:
        super().__init__(model)
        self.team = team

    def compose(self) -> ComposeResult:
        yield MatchBar(self.model, f"robo_comp · team {self.team}")
        with Horizontal(id="body"):
            with Vertical(id="left"):
                robots = RobotsTable(id="robots")
                robots.border_title = "Robots"
                yield robots
                yield EventLog(id="log")
            with Vertical(id="right"):
                yield MonitorPanel(id="monitor")
                yield MapView(self.model, id="map")
        yield Footer(compact=True)

    def on_data_table_row_selected(self, event: RobotsTable.RowSelected) -> None:
        """``enter`` on a robot opens the task form (the thesis's "3. Give task to a robot")."""
        event.stop()
        app = self.app
        assert isinstance(app, GivesTasks), "the team screen is the team console's"
        app.action_give_task()

    def set_team(self, team: str) -> None:
        """The hello told us the team's name."""
        self.team = team
        self.query_one(MatchBar).title = f"robo_comp · team {team}"

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        if action == "view":
            return True if self.has_class("-narrow") else False
        return True


__all__: list[Any] = ["ConsoleScreen", "TeamScreen"]

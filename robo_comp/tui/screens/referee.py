"""The referee console's main screen: the whole match: phase, scores, every robot, the event log."""
from __future__ import annotations

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.widgets import Footer, Input, Select

from robo_comp.tui.model import ConsoleModel
from robo_comp.tui.screens.team import ConsoleScreen
from robo_comp.tui.widgets.core_line import CoreLine
from robo_comp.tui.widgets.event_log import EventLog
from robo_comp.tui.widgets.map_view import MapView
from robo_comp.tui.widgets.monitor import MonitorPanel
from robo_comp.tui.widgets.robots_table import RobotsTable
from robo_comp.tui.widgets.score import MatchBar, ScoreTable


class RefereeScreen(ConsoleScreen):
    """Scores, the core's line (outage rule, recovery), all robots, monitor and map, and the
    filtered event log."""

    BINDINGS = [
        Binding("g", "app.match('start')", "Start"),
        Binding("p", "app.pause_resume", "Pause", tooltip="Pause a running match, resume a paused one"),
        Binding("f", "app.match('finish')", "Finish"),
        Binding("e", "app.extend", "Extend", show=False),
        Binding("n", "app.penalty", "Penalty"),
        Binding("d", "app.disqualify", "Disqualify"),
        Binding("b", "app.broadcast", "Broadcast"),
        Binding("a", "app.approve", "Approve", show=False),
        Binding("l", "app.leaderboard", "League", show=False, tooltip="The league's leaderboard (--league)"),
        Binding("o", "app.outage", "Outage", show=False, tooltip="What a core outage does to the match clock"),
        Binding("r", "app.recovery", "Recovery", show=False, tooltip="What the core recovered from its log"),
        Binding("slash", "filter", "Filter", show=False),
        Binding("v", "view", "View", show=False),
    ]

    def __init__(self, model: ConsoleModel) -> None:
        super().__init__(model)
        self.panel = "log"
        self._filter_teams: list[str] = []

    def compose(self) -> ComposeResult:
        yield MatchBar(self.model, "robo_comp · referee")
        with Horizontal(id="body"):
            with Vertical(id="left"):
                scores = ScoreTable(id="scores")
                scores.border_title = "Scores"
                yield scores
                yield CoreLine(self.model, id="core-line")
                robots = RobotsTable(show_team=True, id="robots")
                robots.border_title = "Robots"
                yield robots
            with Vertical(id="right"):
                with Horizontal(id="filters"):
                    yield Input(placeholder="filter events (text) — / to focus", id="filter", compact=True)
                    yield Select([], prompt="all teams", id="team-filter", compact=True)
                yield EventLog(id="log")
                yield MonitorPanel(id="monitor")
                yield MapView(self.model, id="map")
        yield Footer(compact=True)

    def refresh_views(self) -> None:
        super().refresh_views()
        self.query_one(ScoreTable).update_from(self.model)
        self.query_one(CoreLine).update_from(self.model)
        if self.model.teams != self._filter_teams:
            self._filter_teams = list(self.model.teams)
            self.query_one("#team-filter", Select).set_options([(t, t) for t in self._filter_teams])

    def action_filter(self) -> None:
        self.query_one("#filter", Input).focus()

    def _apply_filter(self) -> None:
        team = self.query_one("#team-filter", Select).value
        self.query_one(EventLog).set_filter(self.model.events, self.query_one("#filter", Input).value,
                                            team if isinstance(team, str) else None)

    @on(Input.Changed, "#filter")
    def _filter_changed(self, event: Input.Changed) -> None:
        self._apply_filter()

    @on(Input.Submitted, "#filter")
    def _filter_done(self, event: Input.Submitted) -> None:
        self.query_one(RobotsTable).focus()

    @on(Select.Changed, "#team-filter")
    def _team_changed(self, event: Select.Changed) -> None:
        self._apply_filter()

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        if action == "view":
            return True if self.has_class("-narrow") else False
        return True

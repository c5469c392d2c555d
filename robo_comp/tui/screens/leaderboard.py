"""The league's leaderboard in the referee console (``robo-comp referee --league LEAGUE``, key ``l``).

It shows the standings of :func:`robo_comp.league.season.league_view` (plain data); ``r``
asks the app to read the league again (:class:`LeaderboardScreen.RefreshRequested`), ``escape``
goes back to the match.
"""
from __future__ import annotations

from typing import Any

from textual.app import ComposeResult
from textual.binding import Binding
from textual.message import Message
from textual.screen import Screen
from textual.widgets import DataTable, Footer, Label

COLUMNS = (("#", "rank"), ("team", "team"), ("version", "version"), ("rating μ−3σ", "rating"), ("μ", "mu"),
           ("σ", "sigma"), ("matches", "matches"), ("wins", "wins"), ("mean score", "mean_score"))


class LeaderboardScreen(Screen[None]):
    """The league's standings, best first."""

    BINDINGS = [Binding("r", "refresh_view", "Refresh"), Binding("escape", "app.pop_screen", "Back")]

    class RefreshRequested(Message):
        """The referee asked for the league to be read again."""

    def __init__(self, view: dict[str, Any]) -> None:
        super().__init__(classes="leaderboard-screen")
        self.view = view

    def compose(self) -> ComposeResult:
        yield Label("", id="league-title")
        yield DataTable(id="standings", zebra_stripes=True, cursor_type="row")
        yield Label("", id="league-footer")
        yield Footer()

    def on_mount(self) -> None:
        table = self.query_one("#standings", DataTable)
        for heading, key in COLUMNS:
            table.add_column(heading, key=key)
        self.update_view(self.view)

    def update_view(self, view: dict[str, Any]) -> None:
        """Show ``view`` (the standings are refilled)."""
        self.view = view
        table = self.query_one("#standings", DataTable)
        table.clear()
        for row in view["standings"]:
            cells = [_cell(row.get(key)) for _, key in COLUMNS]
            if row.get("provisional"):  # σ still too large to trust the rank (ratings.SURE_SIGMA)
                cells[3] += " ?"
            table.add_row(*cells, key=row["team"])
        played = sum(1 for m in view["matches"] if m.get("status") == "done")
        waiting = sum(1 for m in view["matches"] if m.get("status") != "done")
        self.query_one("#league-title", Label).update(f"League: {view['name']}")
        unsure = " · ?: provisional (σ too large to trust the rank)" if any(
            r.get("provisional") for r in view["standings"]) else ""
        self.query_one("#league-footer", Label).update(
            f"{played} matches played, {waiting} waiting{unsure} · r: refresh · escape: back to the match")

    def action_refresh_view(self) -> None:
        """Ask the app for a fresh view."""
        self.post_message(self.RefreshRequested())

    def teams(self) -> list[str]:
        """The teams in the table's order (for tests and the command palette)."""
        table = self.query_one("#standings", DataTable)
        return [str(table.get_row_at(i)[1]) for i in range(table.row_count)]


def _cell(v: Any) -> str:
    if v is None:
        return "–"
    return f"{v:.2f}" if isinstance(v, float) else str(v)


__all__ = ["LeaderboardScreen"]

"""The match bar (who, phase, clock, score, link) and the referee's score table."""
from __future__ import annotations

from rich.text import Text
from textual.reactive import reactive
from textual.widget import Widget
from textual.widgets import DataTable

from robo_comp.tui.model import ConsoleModel, fmt_clock

PHASE_STYLE = {"setup": "bold white on blue", "running": "bold black on green",
               "paused": "bold black on yellow", "finished": "bold white on grey37"}
LINK_STYLE = {"connected": ("● online", "green"), "connecting": ("… connecting", "yellow"),
              "reconnecting": ("⟳ reconnecting…", "bold red"), "closed": ("✗ offline", "bold red")}



def clock_text(phase: str, elapsed: float, remaining: float | None) -> str:
    """The status bar's clock: time left while the match can still run; once it is finished,
    how long it ran (a finished match has no time "left")."""
    if phase == "finished":
        return f"{fmt_clock(elapsed)} played"
    return f"{fmt_clock(remaining)} left" if remaining is not None else f"{fmt_clock(elapsed)} elapsed"

class MatchBar(Widget):
    """One line at the top: console name, match phase and clock, the team's score, the link state."""

    DEFAULT_CSS = """
    MatchBar { height: 1; dock: top; background: $panel; }
    """

    link: reactive[str] = reactive("connecting")

    def __init__(self, model: ConsoleModel, title: str, id: str | None = None) -> None:
        super().__init__(id=id)
        self.model = model
        self.title = title

    def on_mount(self) -> None:
        self.set_interval(0.5, self.refresh)

    def render(self) -> Text:
        m = self.model
        width = self.size.width
        elapsed, remaining = m.match.now(m.clock())
        label, link_style = LINK_STYLE.get(self.link, (self.link, ""))
        clock = clock_text(m.match.phase, elapsed, remaining)
        mine = m.my_score()
        score = ""
        if mine is not None:
            score = f"score {mine.get('score', 0):g} rank {mine.get('rank', '?')}/{len(m.scores)}"
        elif m.role == "referee" and m.scores:
            score = f"lead {m.scores[0].get('team')} {m.scores[0].get('score', 0):g}"
        title = self.title
        # drop what matters least until the line fits: the link state always stays visible
        for attempt in range(3):
            used = len(title) + 2 + len(m.match.phase) + 3 + len(clock) + 1 + (len(score) + 5 if score else 0)
            if used + len(label) + 2 <= width:
                break
            if attempt == 0:
                title = title.replace("robo_comp · ", "")
            elif attempt == 1:
                clock = clock.replace(" elapsed", "").replace(" left", "").replace(" played", "")
        t = Text(no_wrap=True, overflow="ellipsis")
        t.append(f" {title} ", style="bold")
        t.append(f" {m.match.phase.upper()} ", style=PHASE_STYLE.get(m.match.phase, "reverse"))
        t.append(f" {clock}", style="bold")
        if score:
            t.append("  │  ", style="dim")
            t.append(score, style="bold")
        t.truncate(max(0, width - len(label) - 2), overflow="ellipsis")
        t.append(" " * max(1, width - t.cell_len - len(label) - 1))
        t.append(label, style=link_style)
        return t


class ScoreTable(DataTable[object]):
    """Teams ranked by score, with victims found, penalties and disqualification."""

    DEFAULT_CSS = """
    ScoreTable { height: auto; max-height: 10; }
    """

    def __init__(self, id: str | None = None) -> None:
        super().__init__(id=id, cursor_type="row", zebra_stripes=True)
        self._last: list[tuple[object, ...]] = []
        #: The highlighted team (the penalty form's first choice): its rank carries a ``▸``, so the
        #: choice is seen without the cursor's colour.
        self.marked: str | None = None

    def on_mount(self) -> None:
        for name, key, w in (("#", "rank", 3), ("team", "team", 10), ("score", "score", 7),
                             ("victims", "victims", 7), ("penalties", "penalties", 9),
                             ("robots", "robots", 6), ("", "dq", 4)):
            self.add_column(name, key=key, width=w)

    @property
    def selected_team(self) -> str | None:
        """The highlighted team."""
        if not self.row_count:
            return None
        key = self.coordinate_to_cell_key(self.cursor_coordinate).row_key
        return str(key.value) if key.value is not None else None

    def update_from(self, model: ConsoleModel) -> None:
        """Redraw when the scores or robot counts changed."""
        counts: dict[str, int] = {}
        for r in model.robots.values():
            counts[r.get("team", "?")] = counts.get(r.get("team", "?"), 0) + 1
        rows = model.scores or [{"team": t, "rank": i + 1, "score": 0, "victims": 0, "penalties": 0}
                                for i, t in enumerate(model.teams)]
        new: list[tuple[object, ...]] = [
            (self._rank(r.get("rank", "?"), r.get("team", "?")), r.get("team", "?"), f"{r.get('score', 0):g}", r.get("victims", 0),
             f"{r.get('penalties', 0):g}", counts.get(r.get("team", ""), 0),
             Text("DQ", style="bold magenta") if r.get("disqualified") else "") for r in rows]
        if new == self._last:
            return
        cursor = self.cursor_row
        self.clear()
        for row in new:
            self.add_row(*row, key=str(row[1]))
        self._last = new
        if self.row_count:
            self.move_cursor(row=min(cursor, self.row_count - 1))

    def _rank(self, rank: object, team: object) -> str:
        return f"{'▸' if team == self.marked else ' '}{rank}"

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        """Move the ``▸`` to the highlighted team."""
        old, self.marked = self.marked, str(event.row_key.value) if event.row_key.value is not None else None
        for i, row in enumerate(self._last):
            if row[1] in (old, self.marked):
                rank = str(row[0]).lstrip("▸ ")
                self._last[i] = (self._rank(rank, row[1]), *row[1:])
                self.update_cell(str(row[1]), "rank", self._last[i][0])

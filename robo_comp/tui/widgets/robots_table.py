"""The robots table: every robot of the team (all robots for the referee) at a glance, live.

The highlighted robot is the selected one (monitor, map, STOP): its tag carries a ``▸``, so the
choice is seen without the cursor's colour."""
from __future__ import annotations

from typing import Any

from rich.text import Text
from textual.widgets import DataTable

from robo_comp.tui.messages import RobotSelected
from robo_comp.tui.model import ConsoleModel, task_label

STATUS_STYLE = {"connected": "green", "lost": "bold red", "left": "dim", "disqualified": "magenta"}


def status_text(status: str, moving: bool = False) -> Text:
    """A coloured status cell (``▶`` while moving)."""
    t = Text(status, style=STATUS_STYLE.get(status, ""))
    if moving and status == "connected":
        t.append(" ▶", style="cyan")
    return t


class RobotsTable(DataTable[Any]):
    """A live table of robots; highlighting a row selects the robot (:class:`RobotSelected`)."""

    DEFAULT_CSS = """
    RobotsTable { height: 1fr; }
    """

    def __init__(self, *, show_team: bool = False, id: str | None = None) -> None:
        super().__init__(id=id, cursor_type="row", zebra_stripes=True)
        self.show_team = show_team
        self._rows: dict[int, tuple[Any, ...]] = {}
        #: The robot whose tag carries the ``▸`` (the highlighted row).
        self.marked: int | None = None

    def on_mount(self) -> None:
        self.add_column("tag", key="tag", width=5)
        if self.show_team:
            self.add_column("team", key="team", width=6)
        self.add_column("status", key="status", width=12)
        self.add_column("position", key="pos", width=11)
        self.add_column("hdg", key="heading", width=4)
        self.add_column("task", key="task", width=22)
        self.add_column("queue", key="queue", width=5)

    @property
    def selected_tag(self) -> int | None:
        """The tag of the highlighted robot."""
        if not self.row_count:
            return None
        try:
            key = self.coordinate_to_cell_key(self.cursor_coordinate).row_key
        except Exception:
            return None
        return int(key.value) if key.value is not None else None

    def select_tag(self, tag: int) -> None:
        """Move the cursor to robot ``tag``."""
        if tag in self._rows:
            self.move_cursor(row=self.get_row_index(str(tag)))

    def _tag_cell(self, tag: int) -> Text:
        return Text(f"{'▸' if tag == self.marked else ' '}{tag}", style="bold")

    def _cells(self, r: dict[str, Any]) -> tuple[Any, ...]:
        cells: list[Any] = [self._tag_cell(r["tag"])]
        if self.show_team:
            cells.append(r.get("team", ""))
        cells += [status_text(r.get("status", "?"), bool(r.get("moving"))),
                  f"{r.get('x', 0.0):5.1f},{r.get('y', 0.0):5.1f}",
                  f"{r.get('heading', 0.0):3.0f}°", task_label(r.get("task")),
                  str(r.get("queue", 0) or 0)]
        return tuple(cells)

    def update_from(self, model: ConsoleModel) -> None:
        """Bring the rows in step with the model (changed cells only)."""
        keys = [c for c in self.columns]
        seen = set()
        for tag in sorted(model.robots):
            seen.add(tag)
            cells = self._cells(model.robots[tag])
            old = self._rows.get(tag)
            if old is None:
                self.add_row(*cells, key=str(tag))
            elif old != cells:
                for col, (a, b) in zip(keys, zip(old, cells)):
                    if a != b:
                        self.update_cell(str(tag), col, b)
            self._rows[tag] = cells
        for tag in set(self._rows) - seen:
            self.remove_row(str(tag))
            del self._rows[tag]

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        event.stop()
        key = event.row_key.value if event.row_key is not None else None
        tag = int(key) if key is not None else None
        old, self.marked = self.marked, tag
        for t in (old, tag):
            if t is not None and t in self._rows:
                self._rows[t] = (self._tag_cell(t), *self._rows[t][1:])
                self.update_cell(str(t), "tag", self._rows[t][0])
        self.post_message(RobotSelected(tag))

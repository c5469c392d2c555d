"""A small map: known walls, robots (the selected one highlighted) and finds, fitted to the panel.

A terminal character is about twice as high as it is wide, so each character shows two square
"pixels", one above the other (``▀`` ``▄`` ``█``): an arena cell is one pixel wide and one pixel
high at the smallest scale, and every scale keeps the arena's aspect ratio. Where the panel has
fewer pixels than the arena has cells, a pixel is a wall if any cell under it is (walls never
vanish). Everything is told by a character, not by colour alone: the legend names which robots
are whose and which one is selected, and a refused find looks unlike a confirmed one.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from rich.style import Style
from rich.text import Text
from textual import events
from textual.geometry import Size
from textual.widget import Widget

from robo_comp.tui.messages import RobotSelected
from robo_comp.tui.model import ConsoleModel

TEAM_COLOURS = ("red", "dodger_blue1", "green3", "dark_orange", "medium_purple", "tan")
#: Characters by (top pixel is a wall, bottom pixel is a wall).
HALF_BLOCKS = {(False, False): "·", (True, False): "▀", (False, True): "▄", (True, True): "█"}
#: Robot digits named per team in the legend before "…".
LEGEND_ROBOTS = 10


def fit(rows: int, cols: int, width: int, lines: int) -> float:
    """Pixels per arena cell so that the arena fits ``width`` characters and ``lines`` lines
    (two pixels a line)."""
    return min(2 * lines / rows, width / cols)


def sample(walls: np.ndarray, scale: float) -> np.ndarray:
    """The walls as ``floor(rows·scale) × floor(cols·scale)`` pixels: above one pixel per cell
    each pixel shows the cell under it; below, a pixel is a wall if any cell it covers is."""
    rows, cols = walls.shape
    out_h, out_w = max(1, math.floor(rows * scale)), max(1, math.floor(cols * scale))
    at = 0.5 if scale >= 1 else 0.0  # enlarged: the cell under each pixel's centre (walls of even width)
    ys = np.minimum(((np.arange(out_h) + at) / scale).astype(np.intp), rows - 1)
    xs = np.minimum(((np.arange(out_w) + at) / scale).astype(np.intp), cols - 1)
    # reduceat ORs each run [start_i, start_i+1); a repeated start takes that one row or column
    return np.logical_or.reduceat(np.logical_or.reduceat(walls, ys, axis=0), xs, axis=1)


class MapView(Widget):
    """The arena drawn in characters: walls in half blocks, robots by the last digit of their tag,
    ``✗`` lost, ``+`` a confirmed find, ``-`` a refused one; a legend below."""

    DEFAULT_CSS = """
    MapView { height: 1fr; min-height: 6; }
    """

    def __init__(self, model: ConsoleModel, id: str | None = None) -> None:
        super().__init__(id=id)
        self.model = model
        self.selected: int | None = None
        self.border_title = "Map"
        self._cache: tuple[Any, list[list[str]], list[list[str | None]]] | None = None
        #: Pixels per cell of the last drawing (None before it).
        self.scale: float | None = None
        self._wanted = -1

    def _colour(self, team: str | None) -> str:
        teams = self.model.teams
        return TEAM_COLOURS[teams.index(team) % len(TEAM_COLOURS)] if team in teams else "white"

    # ------------------------------------------------------------------ size
    def legend(self, width: int) -> list[str]:
        """The legend's lines: the symbols, then (where more than one team is on the map) whose
        robots are which, and the selected robot; items are packed into lines of ``width``."""
        m = self.model
        rows, cols = m.walls.shape if m.walls is not None else (0, 0)
        items = [f"{cols}×{rows}", "█ wall", "0-9 robot", "✗ lost", "+ find", "- refused"]
        shown = [(t, r) for t, r in sorted(m.robots.items()) if r.get("status") != "left"]
        if len({r.get("team") for _, r in shown}) > 1:
            for team in m.teams:
                digits = [str(t % 10) for t, r in shown if r.get("team") == team]
                if digits:
                    more = " …" if len(digits) > LEGEND_ROBOTS else ""
                    items.append(f"{team} {' '.join(digits[:LEGEND_ROBOTS])}{more}")
        if self.selected is not None and self.selected in m.robots:
            items.append(f"▸ {self.selected} selected")
        lines: list[str] = []
        for item in items:
            if lines and len(lines[-1]) + 3 + len(item) <= width:
                lines[-1] += " · " + item
            else:
                lines.append(item if len(item) <= width else item[:max(0, width - 1)] + "…")
        return lines

    def get_content_height(self, container: Size, viewport: Size, width: int) -> int:
        """As high as the arena is at this width (for ``height: auto``)."""
        walls = self.model.walls
        if walls is None or width < 4:
            return 3
        rows, cols = walls.shape
        return math.ceil(rows * (width / cols) / 2) + len(self.legend(width))

    def cell_to_screen(self, x: float, y: float) -> tuple[int, int] | None:
        """The (column, line) inside the panel where a robot at ``(x, y)`` is drawn (None before
        the first drawing)."""
        if self.scale is None:
            return None
        return int((x + 0.5) * self.scale), int((y + 0.5) * self.scale / 2)

    def update_map(self) -> None:
        """Redraw; lay the panel out again first when the height it asks for changed (the walls
        arrived, the legend grew a line)."""
        wanted = self.get_content_height(self.content_size, self.content_size, self.content_size.width)
        if wanted != self._wanted:
            self._wanted = wanted
            self.refresh(layout=True)
        else:
            self.refresh()

    # ------------------------------------------------------------------ drawing
    def render(self) -> Text:
        m = self.model
        w = self.content_size.width
        legend = self.legend(w)
        lines = self.content_size.height - len(legend)
        if m.walls is None or w < 4 or lines < 1:
            return Text("no map yet", style="dim")
        rows, cols = m.walls.shape
        s = fit(rows, cols, w, lines)
        self.scale = s
        key = (s, id(m.walls))
        if self._cache is None or self._cache[0] != key:
            self._cache = (key, *self._background(m.walls, s))
        grid = [row[:] for row in self._cache[1]]
        styles = [row[:] for row in self._cache[2]]
        self._paint(grid, styles)
        text = Text(no_wrap=True)
        for g, st in zip(grid, styles):
            for ch, style in zip(g, st):
                text.append(ch, Style.parse(style) if style else None)
            text.append("\n")
        text.append("\n".join(legend), style="dim")
        return text

    def on_click(self, event: events.Click) -> None:
        """Clicking next to a robot selects it (:class:`RobotSelected`)."""
        off = event.get_content_offset(self)
        if off is None or self.scale is None:
            return
        s = self.scale
        x, y = (off.x + 0.5) / s, (2 * off.y + 1) / s
        near = [(math.hypot(r.get("x", 0) + 0.5 - x, r.get("y", 0) + 0.5 - y), tag)
                for tag, r in self.model.robots.items() if r.get("status") != "left"]
        if near and min(near)[0] <= max(2.0, 2.0 / s):
            self.post_message(RobotSelected(min(near)[1]))

    @staticmethod
    def _background(walls: np.ndarray, s: float) -> tuple[list[list[str]], list[list[str | None]]]:
        """The walls in half blocks, two pixels a character."""
        px = sample(walls, s)
        if px.shape[0] % 2:
            px = np.vstack([px, np.zeros((1, px.shape[1]), dtype=bool)])
        grid: list[list[str]] = []
        styles: list[list[str | None]] = []
        for top, bottom in zip(px[0::2].tolist(), px[1::2].tolist()):
            grid.append([HALF_BLOCKS[(a, b)] for a, b in zip(top, bottom)])
            styles.append(["grey23" if not (a or b) else "grey50" for a, b in zip(top, bottom)])
        return grid, styles

    def _paint(self, grid: list[list[str]], styles: list[list[str | None]]) -> None:
        """Finds and robots over the walls."""
        m = self.model
        out_h, out_w = len(grid), len(grid[0]) if grid else 0

        def put(x: float, y: float, ch: str, style: str) -> None:
            at = self.cell_to_screen(x, y)
            if at is not None and 0 <= at[1] < out_h and 0 <= at[0] < out_w:
                grid[at[1]][at[0]] = ch
                styles[at[1]][at[0]] = style

        for f in m.finds:
            state = f.get("state") or ("confirmed" if (f.get("verdict") or {}).get("valid") else "")
            ok = state == "confirmed"
            put(float(f.get("x", 0)), float(f.get("y", 0)), "+" if ok else "-", "bold green" if ok else "yellow")
        for tag, rob in sorted(m.robots.items()):
            status = rob.get("status")
            if status == "left":
                continue
            ch = "✗" if status in ("lost", "disqualified") else str(tag % 10)
            style = "bold " + self._colour(rob.get("team"))
            if tag == self.selected:
                style = "bold reverse " + self._colour(rob.get("team"))
            put(float(rob.get("x", 0)), float(rob.get("y", 0)), ch, style)

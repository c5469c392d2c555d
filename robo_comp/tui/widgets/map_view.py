"""A small map: known walls, robots (the selected one highlighted) and finds, fitted to the panel."""
from __future__ import annotations

import math
from typing import Any

from rich.style import Style
from rich.text import Text
from textual import events
from textual.widget import Widget

from robo_comp.tui.messages import RobotSelected
from robo_comp.tui.model import ConsoleModel

TEAM_COLOURS = ("red", "dodger_blue1", "green3", "dark_orange", "medium_purple", "tan")


class MapView(Widget):
    """The arena drawn in characters: ``█`` walls, robots by the last digit of their tag, ``+`` finds."""

    DEFAULT_CSS = """
    MapView { height: 1fr; min-height: 6; }
    """

    def __init__(self, model: ConsoleModel, id: str | None = None) -> None:
        super().__init__(id=id)
        self.model = model
        self.selected: int | None = None
        self.border_title = "Map"
        self._cache: tuple[Any, list[list[str]], list[list[str | None]]] | None = None
        self._scale: tuple[float, float] | None = None

    def _colour(self, team: str | None) -> str:
        teams = self.model.teams
        return TEAM_COLOURS[teams.index(team) % len(TEAM_COLOURS)] if team in teams else "white"

    def render(self) -> Text:
        m = self.model
        w, h = self.content_size.width, self.content_size.height - 1
        if m.walls is None or w < 4 or h < 2:
            return Text("no map yet", style="dim")
        rows, cols = m.walls.shape
        # a cell is cx characters wide and cy lines high, twice as wide as high (square on screen)
        cy = min(h / rows, w / (2 * cols))
        cx = 2 * cy
        out_w, out_h = max(1, min(w, math.floor(cols * cx))), max(1, min(h, math.floor(rows * cy)))
        self._scale = (cx, cy)
        key = (w, h, id(m.walls))
        if self._cache is None or self._cache[0] != key:
            self._cache = (key, *self._background(out_w, out_h, cx, cy))
        grid = [row[:] for row in self._cache[1]]
        styles = [row[:] for row in self._cache[2]]
        self._paint(grid, styles, cx, cy)
        text = Text(no_wrap=True)
        for r in range(out_h):
            for c in range(out_w):
                text.append(grid[r][c], Style.parse(styles[r][c]) if styles[r][c] else None)
            text.append("\n")
        text.append(f"{cols}×{rows} cells  █ wall  0-9 robot  ✗ lost  + find", style="dim")
        return text

    def on_click(self, event: events.Click) -> None:
        """Clicking next to a robot selects it (:class:`RobotSelected`)."""
        off = event.get_content_offset(self)
        if off is None or self._scale is None:
            return
        cx, cy = self._scale
        x, y = off.x / cx, off.y / cy
        near = [(math.hypot(r.get("x", 0) + 0.5 - x, r.get("y", 0) + 0.5 - y), tag)
                for tag, r in self.model.robots.items() if r.get("status") != "left"]
        if near and min(near)[0] <= max(2.0, 1.5 / cy):
            self.post_message(RobotSelected(min(near)[1]))

    def _background(self, out_w: int, out_h: int, cx: float, cy: float
                    ) -> tuple[list[list[str]], list[list[str | None]]]:
        """Walls scaled to the panel (a character is a wall if any cell under it is)."""
        walls = self.model.walls
        assert walls is not None
        grid = [[" "] * out_w for _ in range(out_h)]
        styles: list[list[str | None]] = [[None] * out_w for _ in range(out_h)]
        for r in range(out_h):
            y0, y1 = int(r / cy), max(int(r / cy) + 1, math.ceil((r + 1) / cy))
            band = walls[y0:y1]
            for c in range(out_w):
                x0, x1 = int(c / cx), max(int(c / cx) + 1, math.ceil((c + 1) / cx))
                if band[:, x0:x1].any():
                    grid[r][c] = "█"
                    styles[r][c] = "grey50"
                else:
                    grid[r][c] = "·"
                    styles[r][c] = "grey23"
        return grid, styles

    def _paint(self, grid: list[list[str]], styles: list[list[str | None]], cx: float, cy: float) -> None:
        """Finds and robots over the walls."""
        m = self.model
        out_h, out_w = len(grid), len(grid[0]) if grid else 0

        def put(x: float, y: float, ch: str, style: str) -> None:
            c, r = int((x + 0.5) * cx), int((y + 0.5) * cy)
            if 0 <= r < out_h and 0 <= c < out_w:
                grid[r][c] = ch
                styles[r][c] = style

        for f in m.finds:
            state = f.get("state") or ("confirmed" if (f.get("verdict") or {}).get("valid") else "")
            put(float(f.get("x", 0)), float(f.get("y", 0)), "+", "bold green" if state == "confirmed" else "yellow")
        for tag, rob in sorted(m.robots.items()):
            status = rob.get("status")
            if status == "left":
                continue
            ch = "✗" if status in ("lost", "disqualified") else str(tag % 10)
            style = "bold " + self._colour(rob.get("team"))
            if tag == self.selected:
                style = "bold reverse " + self._colour(rob.get("team"))
            put(float(rob.get("x", 0)), float(rob.get("y", 0)), ch, style)

"""Geometry of the wall: the virtual canvas, its tiles, the layout, zoom and pan.

The wall is one *virtual canvas* of ``C×R`` tiles of ``W×H`` pixels; tile ``(c, r)`` shows
the canvas window at ``(c·W, r·H)``. Everything is placed in canvas pixels by integer
arithmetic that does not depend on the tile, and a tile only subtracts its integer origin,
so tiles rendered by different processes stitch edge to edge pixel-exactly.

The arena is scaled to fit the map area (the thesis's zoom factor, 3.8.1), times the user's
``zoom``, and shifted by ``pan`` (in cells, the arena point shown at the map's centre
relative to the arena's centre).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from robo_comp.errors import FieldError

Rect = tuple[int, int, int, int]


def rnd(v: float) -> int:
    """Round half up; the one rounding rule of the wall (numpy uses the same)."""
    return math.floor(v + 0.5)


@dataclass(frozen=True)
class TileSpec:
    """Which window of the virtual canvas this process renders."""

    cols: int = 1
    rows: int = 1
    col: int = 0
    row: int = 0
    width: int = 1280
    height: int = 800

    def __post_init__(self) -> None:
        if self.cols < 1 or self.rows < 1 or self.width < 16 or self.height < 16:
            raise FieldError("the grid needs at least 1×1 tiles of at least 16×16 pixels")
        if not (0 <= self.col < self.cols and 0 <= self.row < self.rows):
            raise FieldError(f"tile {self.col},{self.row} is outside the {self.cols}x{self.rows} grid "
                             "(tiles count from 0,0)")

    @property
    def canvas(self) -> tuple[int, int]:
        """Size of the whole virtual canvas."""
        return self.cols * self.width, self.rows * self.height

    @property
    def origin(self) -> tuple[int, int]:
        """Canvas position of this tile's top-left pixel."""
        return self.col * self.width, self.row * self.height

    @property
    def size(self) -> tuple[int, int]:
        """This tile's size in pixels."""
        return self.width, self.height


@dataclass
class ViewState:
    """What the user changes and a master tile shares: zoom, pan and the open panels."""

    zoom: float = 1.0
    pan_x: float = 0.0
    pan_y: float = 0.0
    monitors: list[int] = field(default_factory=list)
    info: str | None = None
    #: Team code's debug drawing: shown at all (key d), and the teams and robots switched off (D, d on a robot).
    debug: bool = True
    debug_off_teams: list[str] = field(default_factory=list)
    debug_off_robots: list[int] = field(default_factory=list)
    #: The legend over the map's lower left corner (key l).
    legend: bool = True

    def to_dict(self) -> dict[str, Any]:
        """Plain data (sent by a master tile)."""
        return {"zoom": self.zoom, "pan": [self.pan_x, self.pan_y], "monitors": list(self.monitors),
                "info": self.info, "debug": [self.debug, list(self.debug_off_teams), list(self.debug_off_robots)],
                "legend": self.legend}

    def update(self, d: dict[str, Any]) -> None:
        """Take over a master tile's state."""
        self.zoom = float(d.get("zoom", self.zoom))
        pan = d.get("pan") or [self.pan_x, self.pan_y]
        self.pan_x, self.pan_y = float(pan[0]), float(pan[1])
        self.monitors = [int(t) for t in d.get("monitors") or []]
        self.info = d.get("info")
        self.legend = bool(d.get("legend", self.legend))
        debug = d.get("debug")
        if isinstance(debug, list) and len(debug) == 3:
            self.debug = bool(debug[0])
            self.debug_off_teams = [str(t) for t in debug[1] or []]
            self.debug_off_robots = [int(t) for t in debug[2] or []]


@dataclass(frozen=True)
class Layout:
    """Where the map, the message bar and the side panel sit on the canvas."""

    canvas: tuple[int, int]
    ui: float  # text and line scale: 1.0 on a 1400×800 screen
    map: Rect
    bar: Rect
    panel: Rect

    @classmethod
    def of(cls, canvas: tuple[int, int]) -> Layout:
        """The layout of a canvas: map on the left, panel on the right, message bar under the map."""
        cw, ch = canvas
        ui = max(0.6, min(cw / 1400, ch / 800))
        pw = min(rnd(330 * ui), cw * 2 // 5)
        bh = rnd(30 * ui)
        return cls(canvas, ui, (0, 0, cw - pw, ch - bh), (0, ch - bh, cw - pw, bh), (cw - pw, 0, pw, ch))

    def px(self, v: float) -> int:
        """``v`` pixels of a 1400×800 screen on this canvas (at least 1)."""
        return max(1, rnd(v * self.ui))

    def panel_boxes(self, teams: int, info: bool, monitors: list[int], ticker: bool = True) -> dict[Any, Rect]:
        """Boxes in the panel, kept apart by a gap: ``"score"``, ``"info"``, one per monitor tag,
        then ``"ticker"`` (the match's events) in the rest of the panel.

        Monitors that do not fit are left out (the oldest stay): panels never cover the map.
        The ticker is left out when fewer than three of its lines fit below them.
        """
        x, y, w, h = self.panel
        gap = self.px(8)
        line = self.px(20)
        boxes: dict[Any, Rect] = {}
        score_h = line * (3 + max(1, teams)) + gap
        boxes["score"] = (x + gap, y + gap, w - 2 * gap, score_h)
        top = y + 2 * gap + score_h
        if info:
            ih = self.px(250)
            boxes["info"] = (x + gap, top, w - 2 * gap, ih)
            top += ih + gap
        mh = self.px(230)
        for tag in monitors:
            if top + mh > y + h - gap:
                break
            boxes[("monitor", tag)] = (x + gap, top, w - 2 * gap, mh)
            top += mh + gap
        if ticker and y + h - gap - top >= self.px(24) + 3 * self.px(18) + gap:
            boxes["ticker"] = (x + gap, top, w - 2 * gap, y + h - gap - top)
        return boxes


@dataclass(frozen=True)
class MapGeometry:
    """Cells to canvas pixels for one arena, layout and view. Cell ``i`` spans ``[i, i+1)``."""

    scale: float  # pixels per cell
    off_x: float
    off_y: float
    width: int
    height: int
    clip: Rect

    @classmethod
    def of(cls, layout: Layout, arena_w: int, arena_h: int, view: ViewState) -> MapGeometry:
        """Fit the arena into the map area (zoom factor), then apply the user's zoom and pan."""
        mx, my, mw, mh = layout.map
        fit = min(mw / max(1, arena_w), mh / max(1, arena_h))
        s = fit * max(0.05, view.zoom)
        off_x = mx + mw / 2 - (arena_w / 2 + view.pan_x) * s
        off_y = my + mh / 2 - (arena_h / 2 + view.pan_y) * s
        return cls(s, off_x, off_y, arena_w, arena_h, layout.map)

    def edge_x(self, i: float) -> int:
        """Canvas x of the left edge of column ``i``."""
        return rnd(self.off_x + i * self.scale)

    def edge_y(self, j: float) -> int:
        """Canvas y of the top edge of row ``j``."""
        return rnd(self.off_y + j * self.scale)

    def point(self, x: float, y: float) -> tuple[int, int]:
        """Canvas pixel of the arena point ``(x, y)`` (a robot at cell (x, y) stands at x+0.5, y+0.5)."""
        return rnd(self.off_x + x * self.scale), rnd(self.off_y + y * self.scale)

    def cell_centre(self, x: float, y: float) -> tuple[int, int]:
        """Canvas pixel of the centre of the robot/object position ``(x, y)`` in cells.

        The renderer uses this very expression (inlined in its hot loop); keep them the same.
        """
        s = self.scale
        return (math.floor(self.off_x + 0.5 * s + 0.5 + x * s), math.floor(self.off_y + 0.5 * s + 0.5 + y * s))

    def to_arena(self, px: float, py: float) -> tuple[float, float]:
        """Arena coordinates (cells, fractional) of canvas pixel ``(px, py)``'s centre."""
        return (px + 0.5 - self.off_x) / self.scale, (py + 0.5 - self.off_y) / self.scale

    def cell_at(self, px: float, py: float) -> tuple[int, int] | None:
        """The cell under canvas pixel ``(px, py)``, or None outside the arena or the map area."""
        cx, cy, cw, ch = self.clip
        if not (cx <= px < cx + cw and cy <= py < cy + ch):
            return None
        ax, ay = self.to_arena(px, py)
        i, j = math.floor(ax), math.floor(ay)
        if 0 <= i < self.width and 0 <= j < self.height:
            return i, j
        return None


def parse_pair(text: str, sep: str, what: str, kind: type = int) -> tuple[Any, Any]:
    """Parse ``"AxB"``/``"A,B"`` flags with a clear error."""
    try:
        a, b = text.lower().split(sep)
        return kind(a), kind(b)
    except ValueError:
        raise FieldError(f"{what} must look like A{sep}B, got {text!r}") from None

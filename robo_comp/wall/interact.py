"""Clicks and keys → what the wall should do: the thesis's mouse protocol (4.3.3), made explicit.

- click an object (find, discovery, known object, picture) → its info box with pictures;
- double-click a robot → its monitor box (again, or a click on the box header, closes it);
- click a robot, then a point → ``goTo`` once ``path_wait`` seconds pass without a second point
  (or at once with Enter / right click);
- click a robot, then several points, then Enter or right click → ``followPath``;
- Esc drops the selection; + / - / wheel zoom; arrows pan; 0 resets the view.

Nothing here talks to the core or imports pygame: :class:`Interaction` turns clicks in
canvas pixels into :class:`Command` values that the app carries out, so it is easy to test.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from robo_comp.view.model import MatchView
from robo_comp.wall.view import Layout, MapGeometry, Rect, ViewState, rnd

#: Seconds between two clicks on one robot that make a double click.
DOUBLE_CLICK = 0.4
#: Seconds after a single point before it becomes a goTo (a second point starts a path).
PATH_WAIT = 1.0
ZOOM_STEP = 1.25
PAN_STEP = 0.1


@dataclass(frozen=True)
class Command:
    """Something for the app to do: ``give`` a task, or open/close a ``monitor``/``info`` box."""

    kind: str  # give, monitor, info, close
    tag: int | None = None
    task: str = ""
    args: list[Any] = field(default_factory=list)
    key: Any = None


@dataclass(frozen=True)
class Hit:
    """What is under a canvas pixel."""

    kind: str  # robot, thing, box, cell, none
    tag: int | None = None
    key: Any = None
    cell: tuple[int, int] | None = None


def _inside(r: Rect, x: float, y: float) -> bool:
    return r[0] <= x < r[0] + r[2] and r[1] <= y < r[1] + r[3]


class Interaction:
    """The click state machine of one wall process."""

    def __init__(self, model: MatchView, view: ViewState, layout: Layout,
                 geometry: Callable[[], MapGeometry | None], boxes: Callable[[], dict[Any, Rect]],
                 radius: Callable[[MapGeometry], int], *, double_click: float = DOUBLE_CLICK,
                 path_wait: float = PATH_WAIT) -> None:
        self.model = model
        self.view = view
        self.layout = layout
        self.geometry = geometry
        self.boxes = boxes
        self.radius = radius
        self.double_click = double_click
        self.path_wait = path_wait
        self.selected: int | None = None
        self.points: list[tuple[int, int]] = []
        self.last_point_at = 0.0
        self._last_robot_click: tuple[int, float] | None = None

    # ------------------------------------------------------------------ hit testing
    def hit(self, px: float, py: float) -> Hit:
        """The robot, thing, panel box or cell under canvas pixel ``(px, py)``."""
        for key, rect in self.boxes().items():
            if key not in ("score", "ticker") and _inside(rect, px, py):
                header = py < rect[1] + self.layout.px(24)
                return Hit("box", key=key if header else None)
        geom = self.geometry()
        if geom is None or not _inside(geom.clip, px, py):
            return Hit("none")
        rad = self.radius(geom)
        best: int | None = None
        best_d: float = (rad + max(3, rad // 2)) ** 2
        for r in self.model.robots.values():
            if r.status == "left":
                continue
            cx, cy = geom.cell_centre(r.x, r.y)
            d = (cx - px) ** 2 + (cy - py) ** 2
            if d <= best_d:
                best, best_d = r.tag, d
        if best is not None:
            return Hit("robot", tag=best)
        k = max(4, min(rnd(geom.scale * 0.45), self.layout.px(30))) + 2
        for key, t in reversed(self.model.things.items()):  # the newest first: it is drawn on top
            cx, cy = geom.cell_centre(t.x, t.y)
            if abs(cx - px) <= k and abs(cy - py) <= k:
                return Hit("thing", key=key, cell=(math.floor(t.x), math.floor(t.y)))
        cell = geom.cell_at(px, py)
        return Hit("cell", cell=cell) if cell is not None else Hit("none")

    # ------------------------------------------------------------------ input
    def click(self, px: float, py: float, button: int, now: float) -> list[Command]:
        """A mouse press at canvas pixel ``(px, py)`` (button 1 left, 3 right) at time ``now``."""
        if button == 3:
            return self.finish()
        if button != 1:
            return []
        h = self.hit(px, py)
        if h.kind == "box":
            if h.key is None:
                return []
            self.cancel()
            return [Command("close", key=h.key)]
        if h.kind == "robot":
            assert h.tag is not None
            last = self._last_robot_click
            if last is not None and last[0] == h.tag and now - last[1] <= self.double_click and not self.points:
                self._last_robot_click = None
                self.cancel()
                return [Command("monitor", tag=h.tag)]
            out = self.finish() if self.points else []
            self.selected, self.points = h.tag, []
            self._last_robot_click = (h.tag, now)
            return out
        if self.selected is not None and h.cell is not None:
            self.points.append(h.cell)
            self.last_point_at = now
            return []
        if h.kind == "thing":
            return [Command("info", key=h.key)]
        self.cancel()
        return []

    def key(self, name: str, now: float) -> list[Command]:
        """A key by name: ``enter``, ``escape``, ``+``, ``-``, ``0``, ``left``/``right``/``up``/``down``,
        ``d`` (debug drawing: the selected robot's on/off, or all of it with no robot selected) and
        ``D`` (the selected robot's team's debug drawing on/off) and ``l`` (the legend on/off)."""
        if name == "enter":
            return self.finish()
        if name in ("d", "D"):
            self.toggle_debug(name == "D")
            return []
        if name == "l":
            self.view.legend = not self.view.legend
            return []
        if name == "escape":
            self.cancel()
        elif name in ("+", "-"):
            self.zoom(ZOOM_STEP if name == "+" else 1 / ZOOM_STEP)
        elif name == "0":
            self.view.zoom, self.view.pan_x, self.view.pan_y = 1.0, 0.0, 0.0
        elif name in ("left", "right", "up", "down"):
            geom = self.geometry()
            if geom is not None:
                _, _, mw, mh = self.layout.map
                dx = {"left": -1, "right": 1}.get(name, 0) * PAN_STEP * mw / geom.scale
                dy = {"up": -1, "down": 1}.get(name, 0) * PAN_STEP * mh / geom.scale
                self.view.pan_x += dx
                self.view.pan_y += dy
        return []

    def toggle_debug(self, team: bool) -> None:
        """Switch debug drawing: of the selected robot (or its team), or all of it when none is selected."""
        v = self.view
        r = self.model.robots.get(self.selected) if self.selected is not None else None
        if r is None:
            v.debug = not v.debug
        elif team:
            name = str(r.team)
            v.debug_off_teams = [t for t in v.debug_off_teams if t != name] if name in v.debug_off_teams \
                else [*v.debug_off_teams, name]
        else:
            v.debug_off_robots = [t for t in v.debug_off_robots if t != r.tag] if r.tag in v.debug_off_robots \
                else [*v.debug_off_robots, r.tag]

    def zoom(self, factor: float) -> None:
        """Multiply the zoom (kept between 0.1 and 64)."""
        self.view.zoom = min(64.0, max(0.1, self.view.zoom * factor))

    def tick(self, now: float) -> list[Command]:
        """Time passes: a lone point becomes a goTo after ``path_wait`` seconds."""
        if self.selected is not None and len(self.points) == 1 and now - self.last_point_at >= self.path_wait:
            return self.finish()
        return []

    def finish(self) -> list[Command]:
        """End the current command: one point → goTo, several → followPath."""
        tag, pts = self.selected, self.points
        self.cancel()
        if tag is None or not pts:
            return []
        if len(pts) == 1:
            return [Command("give", tag=tag, task="goTo", args=[pts[0][0], pts[0][1]])]
        return [Command("give", tag=tag, task="followPath", args=[[[x, y] for x, y in pts]])]

    def cancel(self) -> None:
        """Drop the selection and its points."""
        self.selected, self.points = None, []

    def hint(self) -> str:
        """What the user can do next (shown in the message bar)."""
        if self.selected is None:
            return ""
        if not self.points:
            return f"robot {self.selected}: click a point (goTo) or several points then Enter (followPath); Esc cancels"
        return f"robot {self.selected}: {len(self.points)} point(s); Enter or right click sends, Esc cancels"

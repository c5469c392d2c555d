"""Drawing the wall onto a pygame Surface: one tile's window of the virtual canvas.

Speed comes from doing little per frame: the static map (walls, cost shading, zones, start
zones, grid) is rendered once per zoom/pan into a tile-sized surface with numpy and blitted;
panels are re-rendered only when their text changes; robots are two circles and a line each;
trail points are converted to pixels once. Rendering is deterministic (integer geometry,
the default font, no smoothing), so screenshots can be checked pixel by pixel and tiles
stitch exactly.
"""
from __future__ import annotations

import io
import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pygame

from robo_comp.view.colours import (
    DISCOVERY, DQ_MARK, FIND_COLOURS, FLOOR, KIND_COLOURS, LOST_MARK, PICTURE, RGB, VICTIM_FOUND, VICTIM_MISSED,
    VIDEO, cell_colours, hex_rgb,
)
from robo_comp.view.legend import LegendEntry, legend
from robo_comp.view.model import Message, Robot, Thing, MatchView
from robo_comp.view.story import Banner, Story, StoryItem, banner, clock_line, clock_text, number_text
from robo_comp.wall.view import Layout, MapGeometry, Rect, TileSpec, ViewState, rnd
from robo_comp.world.video import FPS as VIDEO_FPS

BACKGROUND: RGB = (12, 12, 16)
GRID_SHADE = 0.92
OUTLINE: RGB = (20, 20, 24)
SELECT: RGB = (255, 255, 255)
PATH: RGB = (255, 120, 0)
OBJECT: RGB = (120, 84, 50)
PANEL_BG: RGB = (30, 32, 40)
BOX_BG: RGB = (46, 48, 60)
TEXT: RGB = (236, 236, 240)
DIM: RGB = (160, 162, 176)
ERROR: RGB = (255, 86, 70)
BROADCAST: RGB = (255, 220, 90)
WHITE: RGB = (255, 255, 255)
#: The legend's and the banner's backing over the map (opaque: a plain copy each frame).
OVER_MAP: RGB = (24, 25, 32)
TEXT_CACHE_MAX = 8192

#: Position uncertainty (σ, cells) above which the wall rings a robot with where it may be.
SIGMA_SHOWN = 0.5


def mix(a: RGB, b: RGB, t: float) -> RGB:
    """``a`` moved by ``t`` towards ``b``."""
    return (rnd(a[0] + (b[0] - a[0]) * t), rnd(a[1] + (b[1] - a[1]) * t), rnd(a[2] + (b[2] - a[2]) * t))


def wrap(font: pygame.font.Font, text: str, width: int) -> list[str]:
    """``text`` cut into lines of at most ``width`` pixels at spaces (a word too long is cut)."""
    out: list[str] = []
    line = ""
    for word in text.split():
        cand = f"{line} {word}" if line else word
        if font.size(cand)[0] <= width or not line:
            line = cand
        else:
            out.append(line)
            line = word
        while font.size(line)[0] > width and len(line) > 1:  # one word wider than the line
            cut = max(1, len(line) * width // max(1, font.size(line)[0]))
            out.append(line[:cut])
            line = line[cut:]
    if line:
        out.append(line)
    return out


def draw_unclipped(surf: pygame.Surface, bbox: tuple[int, int, int, int],
                   fn: Callable[[pygame.Surface, int, int], Any]) -> None:
    """Draw ``fn(target, dx, dy)`` as if ``surf`` had no clip rect, then clip the pixels.

    pygame clips a line by moving its end points, which changes how the visible part is
    rasterised; a line cut by a tile edge would then differ from the same line on the
    whole canvas. Shapes whose box ``(x0, y0, x1, y1)`` crosses the clip rect are therefore
    drawn whole on a scratch surface and blitted (blits clip pixel-exactly).
    """
    x0, y0, x1, y1 = bbox
    c = surf.get_clip()
    if c.left <= x0 and c.top <= y0 and x1 < c.right and y1 < c.bottom:
        fn(surf, 0, 0)
    elif not (x1 < c.left or y1 < c.top or x0 >= c.right or y0 >= c.bottom):
        tmp = pygame.Surface((x1 - x0 + 1, y1 - y0 + 1), pygame.SRCALPHA, 32)
        fn(tmp, -x0, -y0)
        surf.blit(tmp, (x0, y0))


def line_box(pts: list[tuple[int, int]], width: int) -> tuple[int, int, int, int]:
    """The pixel box a (poly)line of ``width`` may touch."""
    xs = [p[0] for p in pts]
    ys = [p[1] for p in pts]
    m = width + 1
    return min(xs) - m, min(ys) - m, max(xs) + m, max(ys) + m


def draw_lines(surf: pygame.Surface, colour: RGB, pts: list[tuple[int, int]], width: int = 1,
               closed: bool = False) -> None:
    """``pygame.draw.lines`` that renders the same pixels whatever the clip rect (see :func:`draw_unclipped`)."""
    draw_unclipped(surf, line_box(pts, width), lambda t, dx, dy: pygame.draw.lines(
        t, colour, closed, [(x + dx, y + dy) for x, y in pts], width))


def draw_polygon(surf: pygame.Surface, colour: RGB, pts: list[tuple[int, int]], width: int = 0) -> None:
    """``pygame.draw.polygon``, clip-independent like :func:`draw_lines`."""
    draw_unclipped(surf, line_box(pts, width), lambda t, dx, dy: pygame.draw.polygon(
        t, colour, [(x + dx, y + dy) for x, y in pts], width))


@dataclass
class Overlay:
    """What the user is doing, drawn over the model: selection, path, monitors and info."""

    selected: int | None = None
    points: list[tuple[int, int]] = field(default_factory=list)
    monitor_data: dict[int, dict[str, Any] | str] = field(default_factory=dict)
    info_thing: Thing | None = None
    info_pictures: dict[int, bytes | str] = field(default_factory=dict)
    hint: str = ""
    #: Video id -> its frames (RGB arrays), or why they cannot be shown.
    info_videos: dict[int, list[Any] | str] = field(default_factory=dict)
    #: The match's story (ticker lines, victims revealed at the finish) and the timeline's now
    #: (a replay's position; None live: every line told so far).
    story: Story | None = None
    story_now: float | None = None


def map_pixels(cells: np.ndarray, geom: MapGeometry, origin: tuple[int, int], size: tuple[int, int],
               fmt: pygame.Surface) -> np.ndarray:
    """The static map for the canvas window ``origin``/``size`` as mapped pixels ``[x, y]`` of ``fmt``'s format.

    Each pixel takes the colour of the cell whose canvas edges contain it, so the result does
    not depend on where the window is: tiles stitch exactly. Colours are mapped once per
    distinct cell colour and gathered as 32-bit pixels (a 7168×3072 map takes a fraction of
    a second).
    """
    h, w = cells.shape[:2]
    packed = (cells[..., 0].astype(np.uint32) << 16) | (cells[..., 1].astype(np.uint32) << 8) | cells[..., 2]
    dark = (cells.astype(np.float32) * GRID_SHADE).astype(np.uint8)
    packed_dark = (dark[..., 0].astype(np.uint32) << 16) | (dark[..., 1].astype(np.uint32) << 8) | dark[..., 2]
    both, inverse = np.unique(np.concatenate([packed.ravel(), packed_dark.ravel()]), return_inverse=True)
    mapped = np.array([fmt.map_rgb((int(c) >> 16, (int(c) >> 8) & 255, int(c) & 255)) for c in both], np.int64)
    pix = mapped[inverse].astype(np.uint32)
    cells32, dark32 = pix[:h * w].reshape(h, w).T, pix[h * w:].reshape(h, w).T  # [x, y]
    ex = np.floor(geom.off_x + np.arange(w + 1) * geom.scale + 0.5).astype(np.int64)
    ey = np.floor(geom.off_y + np.arange(h + 1) * geom.scale + 0.5).astype(np.int64)
    xs = np.arange(origin[0], origin[0] + size[0])
    ys = np.arange(origin[1], origin[1] + size[1])
    ix = np.searchsorted(ex, xs, side="right") - 1
    iy = np.searchsorted(ey, ys, side="right") - 1
    cx, cy, cw, ch = geom.clip
    okx = (ix >= 0) & (ix < w) & (xs >= cx) & (xs < cx + cw)
    oky = (iy >= 0) & (iy < h) & (ys >= cy) & (ys < cy + ch)
    ixc, iyc = np.clip(ix, 0, w - 1), np.clip(iy, 0, h - 1)
    out = cells32[ixc][:, iyc]
    if geom.scale >= 8:  # grid lines: the first pixel column/row of every cell, darker
        gx = np.nonzero(xs == ex[np.clip(ix, 0, w)])[0]
        gy = np.nonzero(ys == ey[np.clip(iy, 0, h)])[0]
        out[gx, :] = dark32[ixc[gx]][:, iyc]
        out[:, gy] = dark32[ixc][:, iyc[gy]]
    bg = np.uint32(fmt.map_rgb(BACKGROUND))
    out[~okx, :] = bg
    out[:, ~oky] = bg
    return out


class Renderer:
    """Draws a :class:`MatchView` for one tile of the canvas."""

    def __init__(self, model: MatchView, tile: TileSpec, view: ViewState, *, trails: bool = True) -> None:
        if not pygame.font.get_init():
            pygame.font.init()
        self.model = model
        self.tile = tile
        self.view = view
        self.trails = trails
        self.layout = Layout.of(tile.canvas)
        self._fonts: dict[int, pygame.font.Font] = {}
        self._text: dict[tuple[str, int, RGB], pygame.Surface] = {}
        self._cells: tuple[int, np.ndarray] | None = None
        self._static: tuple[Any, pygame.Surface] | None = None
        self._panel: tuple[Any, pygame.Surface] | None = None
        self._bar: tuple[Any, pygame.Surface] | None = None
        self._legend: tuple[Any, pygame.Surface] | None = None
        self._banner: tuple[Any, pygame.Surface] | None = None
        #: What the last frame showed (for tests): the ticker's lines, the banner (None before the
        #: finish) and the canvas rects of what is drawn over the map (``legend``, ``banner``).
        self.ticker: list[StoryItem] = []
        self.banner: Banner | None = None
        self.over: dict[str, Rect] = {}
        self._generation = model.generation
        self._trail_px: dict[int, tuple[int, deque[tuple[int, int]], tuple[int, int, int, int]]] = {}
        self._trail_geom: Any = None
        self._pictures: dict[int, pygame.Surface | None] = {}
        self._video_frame = 0  # the frame of the info box's video drawn now
        self._dirty: list[tuple[int, int, int, int]] = []  # drawn over in the last frame
        self._on_screen: Any = None
        self._shown: dict[str, Any] = {}
        self._team_rgb: dict[str | None, tuple[RGB, RGB, RGB]] = {}
        #: Canvas rects of the scoreboard rows by team and of panel boxes (for tests and clicks).
        self.score_rows: dict[str, Rect] = {}
        self.boxes: dict[Any, Rect] = {}

    # ------------------------------------------------------------------ geometry
    def geometry(self) -> MapGeometry | None:
        """Cells → canvas pixels for the current arena and view (None before the arena is known)."""
        a = self.model.arena
        if a is None:
            return None
        return MapGeometry.of(self.layout, a.width, a.height, self.view)

    def panel_boxes(self) -> dict[Any, Rect]:
        """The panel's boxes for the current view state."""
        return self.layout.panel_boxes(len(self.model.teams()), bool(self.view.info),
                                       list(self.view.monitors))

    def robot_radius(self, geom: MapGeometry) -> int:
        """Robot radius in pixels at this zoom."""
        return max(3, min(rnd(geom.scale * 0.42), self.layout.px(40)))

    # ------------------------------------------------------------------ text
    def font(self, size: int) -> pygame.font.Font:
        """The default font at ``size`` pixels (cached)."""
        f = self._fonts.get(size)
        if f is None:
            f = self._fonts[size] = pygame.font.Font(None, size)
        return f

    def text(self, s: str, size: int, colour: RGB = TEXT) -> pygame.Surface:
        """A rendered line of text (cached)."""
        key = (s, size, colour)
        surf = self._text.get(key)
        if surf is None:
            if len(self._text) > TEXT_CACHE_MAX:
                self._text.clear()
            surf = self._text[key] = self.font(size).render(s, True, colour)
        return surf

    # ------------------------------------------------------------------ the frame
    def draw(self, surf: pygame.Surface, now: float | None = None, overlay: Overlay | None = None, *,
             incremental: bool = False) -> None:
        """Draw the whole tile onto ``surf`` (``now``: monotonic time for the clock; None = as heard).

        ``incremental``: ``surf`` still holds this renderer's previous frame (a window), so only
        the places drawn over last time are restored from the static map, and the panel and bar
        are blitted only when they changed. The pixels are the same as a full redraw.
        """
        overlay = overlay or Overlay()
        geom = self.geometry()
        if geom is None:
            surf.fill(BACKGROUND)
            self._blit_canvas(surf, self.text("waiting for the core's snapshot...", self.layout.px(28), DIM),
                              (self.layout.px(20), self.layout.px(20)))
            self._on_screen = None
            return
        static = self._static_for(surf, geom)
        ox, oy = self.tile.origin
        mx, my, mw, mh = self.layout.map
        clip = pygame.Rect(mx - ox, my - oy, mw, mh).clip(surf.get_rect())
        full = (not incremental or self._on_screen != (id(surf), self._static[0] if self._static else None)
                # many robots with long trails: one blit of the whole map is cheaper than many
                or sum(w * h for _, _, w, h in self._dirty) > surf.get_width() * surf.get_height() // 3)
        if full:
            surf.blit(static, (0, 0))
            self._shown = {}
        elif clip.width > 0 and clip.height > 0:
            surf.set_clip(clip)
            blit = surf.blit
            for x, y, w, h in self._dirty:
                blit(static, (x, y), (x, y, w, h))
            surf.set_clip(None)
        self._dirty = []
        self.over = {}
        if clip.width > 0 and clip.height > 0:
            surf.set_clip(clip)
            self._draw_things(surf, geom)
            if self.trails:
                self._draw_trails(surf, geom)
            self._draw_robots(surf, geom)
            if self.view.debug and self.model.debug:
                self._draw_debug(surf, geom)
            self._draw_overlay(surf, geom, overlay)
            if self.model.match.phase == "finished" and overlay.story is not None and overlay.story.victims:
                self._draw_victims(surf, geom, overlay.story.victims)
            if self.view.legend:
                self._draw_legend(surf)
            self._draw_banner(surf, overlay)
            surf.set_clip(None)
        self._draw_panel(surf, now, overlay)
        self._draw_bar(surf, now, overlay)
        self._on_screen = (id(surf), self._static[0] if self._static else None)

    def _show(self, surf: pygame.Surface, name: str, key: Any, src: pygame.Surface, canvas_pos: tuple[int, int]) -> None:
        """Blit a panel/bar surface unless this very one is on screen already (incremental frames)."""
        if self._shown.get(name) is not key:
            self._blit_canvas(surf, src, canvas_pos)
            self._shown[name] = key

    def _blit_canvas(self, surf: pygame.Surface, src: pygame.Surface, canvas_pos: tuple[int, int]) -> None:
        ox, oy = self.tile.origin
        surf.blit(src, (canvas_pos[0] - ox, canvas_pos[1] - oy))

    def _intersects(self, r: Rect) -> bool:
        ox, oy = self.tile.origin
        w, h = self.tile.size
        return r[0] < ox + w and r[0] + r[2] > ox and r[1] < oy + h and r[1] + r[3] > oy

    def _static_for(self, surf: pygame.Surface, geom: MapGeometry) -> pygame.Surface:
        """The static map of this tile at this zoom and pan (built once per zoom level)."""
        a = self.model.arena
        assert a is not None
        if self._cells is None or self._cells[0] != self.model.arena_version:
            self._cells = (self.model.arena_version, cell_colours(a))
            self._static = None
        size = surf.get_size()
        key = (self.model.arena_version, geom, self.tile.origin, size)
        if self._static is None or self._static[0] != key:
            static = pygame.Surface(size, 0, surf)
            pygame.surfarray.blit_array(static, map_pixels(self._cells[1], geom, self.tile.origin, size, static))
            self._static = (key, static)
        return self._static[1]

    def _colours(self, team: str | None) -> tuple[RGB, RGB, RGB]:
        c = self._team_rgb.get(team)
        if c is None:
            base = hex_rgb(self.model.colour(team))
            c = self._team_rgb[team] = (base, mix(base, (128, 128, 128), 0.65), mix(base, FLOOR, 0.55))
        return c

    def _draw_trails(self, surf: pygame.Surface, geom: MapGeometry) -> None:
        if self._trail_geom != geom or self._generation != self.model.generation:  # (a replay seeking back)
            self._generation = self.model.generation
            self._trail_px.clear()
            self._trail_geom = geom
        ox, oy = self.tile.origin
        # canvas pixels first, then the tile's integer origin: tiles agree to the pixel
        s, gx, gy = geom.scale, geom.off_x + 0.5 * geom.scale + 0.5, geom.off_y + 0.5 * geom.scale + 0.5
        floor = math.floor
        c = surf.get_clip()
        cl, ct, cr, cb = c.left, c.top, c.right, c.bottom
        lines = pygame.draw.lines
        cache = self._trail_px
        dirty = self._dirty.append
        for r in self.model.robots.values():
            if r.status == "left" or len(r.trail) < 2:
                continue
            seen = cache.get(r.tag)
            if seen is None or seen[0] != r.trail_n:
                # only new points are converted; the box grows with them and is made exact
                # again every few points (a box too big only costs a slower, still exact draw)
                new = r.trail_n - seen[0] if seen is not None else len(r.trail)
                if seen is None or new >= len(r.trail) or r.trail_n % 16 == 0:
                    pts = deque(((floor(gx + x * s) - ox, floor(gy + y * s) - oy) for x, y in r.trail),
                                maxlen=r.trail.maxlen)
                    box = line_box(list(pts), 1)
                else:
                    pts = seen[1]
                    x0, y0, x1, y1 = seen[2]
                    for i in range(len(r.trail) - new, len(r.trail)):
                        x, y = r.trail[i]
                        p = (floor(gx + x * s) - ox, floor(gy + y * s) - oy)
                        pts.append(p)
                        x0, y0, x1, y1 = min(x0, p[0] - 2), min(y0, p[1] - 2), max(x1, p[0] + 2), max(y1, p[1] + 2)
                    box = (x0, y0, x1, y1)
                seen = cache[r.tag] = (r.trail_n, pts, box)
            _, pts, (x0, y0, x1, y1) = seen
            if x1 < cl or y1 < ct or x0 >= cr or y0 >= cb:
                continue
            colour = self._colours(r.team)[2]
            dirty((x0, y0, x1 - x0 + 1, y1 - y0 + 1))
            if cl <= x0 and ct <= y0 and x1 < cr and y1 < cb:
                lines(surf, colour, False, pts, 1)
            else:
                draw_lines(surf, colour, list(pts), 1)

    def _draw_robots(self, surf: pygame.Surface, geom: MapGeometry) -> None:
        ox, oy = self.tile.origin
        w, h = surf.get_size()
        rad = self.robot_radius(geom)
        s, gx, gy = geom.scale, geom.off_x + 0.5 * geom.scale + 0.5, geom.off_y + 0.5 * geom.scale + 0.5
        floor = math.floor
        circle, line = pygame.draw.circle, pygame.draw.line
        lw = max(1, rad // 4)
        label = rad >= 7
        size = max(12, rad + 4)
        cos, sin, radians = math.cos, math.sin, math.radians
        reach = 2 * rad + lw + 2
        inner = surf.get_clip().inflate(-2 * reach, -2 * reach)  # robots whose lines cannot be clipped
        dirty = self._dirty.append
        box_w, box_h = 2 * reach + 1 + (4 * size if label else 0), 2 * reach + 1 + (size if label else 0)
        for r in self.model.robots.values():
            if r.status == "left":
                continue
            cx, cy = floor(gx + r.x * s) - ox, floor(gy + r.y * s) - oy
            if cx < -rad * 2 or cy < -rad * 2 or cx > w + rad * 2 or cy > h + rad * 2:
                continue
            dirty((cx - reach, cy - reach - (size if label else 0), box_w, box_h))
            base, grey, _ = self._colours(r.team)
            ok = r.status == "connected"
            if r.sigma > SIGMA_SHOWN:  # where it may be: a ring of radius 2σ (no camera sees it now)
                ring = min(int(2 * r.sigma * s), reach)
                if ring > rad:
                    circle(surf, grey, (cx, cy), ring, 1)
            circle(surf, base if ok else grey, (cx, cy), rad)
            if rad >= 4:
                circle(surf, OUTLINE, (cx, cy), rad, 1)
            a = radians(r.heading)
            dx, dy = cos(a), sin(a)
            p1 = (cx + floor(dx * rad * 0.35 + 0.5), cy + floor(dy * rad * 0.35 + 0.5))
            p2 = (cx + floor(dx * rad * 1.7 + 0.5), cy + floor(dy * rad * 1.7 + 0.5))
            if inner.collidepoint(cx, cy):
                line(surf, OUTLINE, p1, p2, lw)
            else:
                draw_lines(surf, OUTLINE, [p1, p2], lw)
            if not ok:
                self._mark(surf, r, cx, cy, rad)
            if label:
                surf.blit(self.text(str(r.tag), size, OUTLINE), (cx + rad // 2 + 2, cy - rad - size + 2))

    def _draw_debug(self, surf: pygame.Surface, geom: MapGeometry) -> None:
        """Team code's debug drawing (robot.draw_dot/line/text): each shown robot's newest frame,
        unless the view switched its team or the robot off (keys d and D)."""
        ox, oy = self.tile.origin
        s, gx, gy = geom.scale, geom.off_x + 0.5 * geom.scale - ox, geom.off_y + 0.5 * geom.scale - oy
        rad = max(2, rnd(s * 0.18))
        lw = max(1, rnd(s * 0.08))
        size = max(12, min(18, rnd(s * 0.6)))
        dirty = self._dirty.append
        off_teams, off_robots = set(self.view.debug_off_teams), set(self.view.debug_off_robots)
        for tag, frame in self.model.debug.items():
            r = self.model.robots.get(tag)
            if tag in off_robots or (r is not None and r.team in off_teams):
                continue
            for shape in frame:
                try:
                    colour = hex_rgb(str(shape[-1]))
                    x, y = rnd(gx + float(shape[1]) * s), rnd(gy + float(shape[2]) * s)
                    if shape[0] == "d":
                        pygame.draw.circle(surf, colour, (x, y), rad)
                        dirty((x - rad - 1, y - rad - 1, 2 * rad + 3, 2 * rad + 3))
                    elif shape[0] == "l":
                        x1, y1 = rnd(gx + float(shape[3]) * s), rnd(gy + float(shape[4]) * s)
                        draw_lines(surf, colour, [(x, y), (x1, y1)], lw)
                        dirty((min(x, x1) - lw - 1, min(y, y1) - lw - 1, abs(x1 - x) + 2 * lw + 3,
                               abs(y1 - y) + 2 * lw + 3))
                    elif shape[0] == "t":
                        img = self.text(str(shape[3])[:32], size, colour)
                        pos = (x, y - img.get_height() // 2)
                        back = pygame.Rect(pos[0] - 2, pos[1], img.get_width() + 4, img.get_height())
                        surf.fill(BACKGROUND, back)
                        surf.blit(img, pos)
                        dirty((back.x, back.y, back.w, back.h))
                except (TypeError, ValueError, IndexError):
                    continue  # a shape the model should not have had: never a reason to stop drawing

    def _mark(self, surf: pygame.Surface, r: Robot, cx: int, cy: int, rad: int) -> None:
        """The lost marker (a yellow cross) or the disqualified marker (a black cross)."""
        colour = LOST_MARK if r.status == "lost" else DQ_MARK
        k = rad + max(2, rad // 2)
        w = max(2, rad // 3)
        draw_lines(surf, colour, [(cx - k, cy - k), (cx + k, cy + k)], w)
        draw_lines(surf, colour, [(cx - k, cy + k), (cx + k, cy - k)], w)

    def _draw_things(self, surf: pygame.Surface, geom: MapGeometry) -> None:
        ox, oy = self.tile.origin
        k = max(4, min(rnd(geom.scale * 0.45), self.layout.px(30)))
        for t in self.model.things.values():
            px, py = geom.cell_centre(t.x, t.y)
            cx, cy = px - ox, py - oy
            self._dirty.append((cx - k - 2, cy - k - 2, 2 * k + 5, 2 * k + 5))
            if t.kind == "find":
                pts = [(cx, cy - k), (cx + k, cy), (cx, cy + k), (cx - k, cy)]
                draw_polygon(surf, FIND_COLOURS.get(t.state, FIND_COLOURS["reported"]), pts)
                draw_polygon(surf, self._colours(t.team)[0], pts, max(2, k // 4))
            elif t.kind == "discovery":
                rect = pygame.Rect(cx - k, cy - k, 2 * k + 1, 2 * k + 1)
                pygame.draw.rect(surf, DISCOVERY, rect)
                pygame.draw.rect(surf, self._colours(t.team)[0], rect, max(1, k // 4))
            elif t.kind == "object":
                rect = pygame.Rect(cx - k, cy - k, 2 * k + 1, 2 * k + 1)
                pygame.draw.rect(surf, OBJECT, rect)
                pygame.draw.rect(surf, OUTLINE, rect, 1)
            elif t.kind == "picture":
                q = max(2, k // 2)
                rect = pygame.Rect(cx - q, cy - q, 2 * q + 1, 2 * q + 1)
                pygame.draw.rect(surf, PICTURE, rect)
                pygame.draw.rect(surf, OUTLINE, rect, 1)
            elif t.kind == "video":
                self._video_mark(surf, cx, cy, k)

    def _draw_victims(self, surf: pygame.Surface, geom: MapGeometry, victims: list[dict[str, Any]]) -> None:
        """The hidden victims, revealed when the match is over: a ring and a cross, green where a
        team found the victim, red where no one did, with its id (as the web page draws them)."""
        ox, oy = self.tile.origin
        rad = max(6, rnd(geom.scale * 0.5))
        size = max(12, min(18, rad + 4))
        dirty = self._dirty.append
        for v in victims:
            try:
                px, py = geom.cell_centre(float(v["x"]), float(v["y"]))
            except (KeyError, TypeError, ValueError):
                continue
            cx, cy = px - ox, py - oy
            colour = VICTIM_FOUND if v.get("found_by") else VICTIM_MISSED
            self._victim_mark(surf, cx, cy, rad, colour)
            label = self.text(str(v.get("id", "")), size, colour)
            back = pygame.Rect(cx + rad + 2, cy - label.get_height() // 2, label.get_width() + 6, label.get_height())
            surf.fill(BACKGROUND, back)
            surf.blit(label, (back.x + 3, back.y))
            dirty((cx - rad - 3, cy - rad - 3, 2 * rad + 7 + back.w + 2, 2 * rad + 7))
            dirty((back.x, back.y, back.w, back.h))

    def _victim_mark(self, surf: pygame.Surface, cx: int, cy: int, rad: int, colour: RGB) -> None:
        """A ring and a cross in ``colour`` over a white one (seen on any floor)."""
        k = rad * 3 // 5
        for c, w in ((WHITE, max(4, rad * 9 // 20)), (colour, max(2, rad * 7 // 25))):
            pygame.draw.circle(surf, c, (cx, cy), rad, w)
            draw_lines(surf, c, [(cx - k, cy), (cx + k, cy)], w)
            draw_lines(surf, c, [(cx, cy - k), (cx, cy + k)], w)

    def _over_map(self, surf: pygame.Surface, name: str, src: pygame.Surface, pos: tuple[int, int]) -> None:
        """Blit ``src`` at canvas position ``pos`` over the map (restored from the static map next frame)."""
        self.over[name] = (pos[0], pos[1], src.get_width(), src.get_height())
        ox, oy = self.tile.origin
        x, y = pos[0] - ox, pos[1] - oy
        surf.blit(src, (x, y))
        self._dirty.append((x, y, src.get_width(), src.get_height()))

    def _draw_legend(self, surf: pygame.Surface) -> None:
        """The legend in the map's lower left corner (key l): what shapes and colours mean."""
        entries = [e for e in legend(self.model) if e.key != "left"]  # the wall does not draw robots that left
        if not entries:
            return
        key = (tuple(entries), self.layout)
        if self._legend is None or self._legend[0] != key:
            self._legend = (key, self._render_legend(entries))
        img = self._legend[1]
        mx, my, mw, mh = self.layout.map
        pad = self.layout.px(8)
        self._over_map(surf, "legend", img, (mx + pad, my + mh - img.get_height() - pad))

    def _render_legend(self, entries: list[LegendEntry]) -> pygame.Surface:
        L = self.layout
        pad, line, size = L.px(8), L.px(17), L.px(16)
        sym = L.px(22)
        rows = max(6, min(-(-len(entries) // 2), (L.map[3] // 3 - 2 * pad - line) // line))  # two columns if they fit
        cols = [entries[i:i + rows] for i in range(0, len(entries), rows)]
        widths = [sym + max(self.font(size).size(e.text)[0] for e in col) + 2 * pad for col in cols]
        head = self.text("legend (l hides it)", size, DIM)
        w = max(sum(widths) + pad, head.get_width() + 2 * pad)
        h = line * (1 + max(len(c) for c in cols)) + 2 * pad
        img = pygame.Surface((w, h), 0, 32)
        img.fill(OVER_MAP)
        img.blit(head, (pad, pad))
        x = pad
        for col, cw in zip(cols, widths):
            y = pad + line
            for e in col:
                self._legend_symbol(img, e, x + sym // 2, y + line // 2, max(4, line * 2 // 5))
                img.blit(self.text(e.text, size, TEXT), (x + sym, y + (line - size) // 2 + L.px(2)))
                y += line
            x += cw
        return img

    def _legend_symbol(self, img: pygame.Surface, e: LegendEntry, cx: int, cy: int, k: int) -> None:
        """The shape the map draws for a legend entry, at ``(cx, cy)`` with half-size ``k``."""
        square = pygame.Rect(cx - k, cy - k, 2 * k + 1, 2 * k + 1)
        if e.key in ("robot", "lost", "disqualified"):
            robot = Robot(0, e.team, status={"robot": "connected"}.get(e.key, e.key))
            pygame.draw.circle(img, e.colour if e.key == "robot" else (150, 150, 150), (cx, cy), k)
            pygame.draw.circle(img, OUTLINE, (cx, cy), k, 1)
            pygame.draw.line(img, OUTLINE, (cx + k // 3, cy), (cx + k * 17 // 10, cy), max(1, k // 4))
            if e.key != "robot":
                self._mark(img, robot, cx, cy, k * 3 // 4)
        elif e.key == "find":
            pts = [(cx, cy - k), (cx + k, cy), (cx, cy + k), (cx - k, cy)]
            pygame.draw.polygon(img, e.colour, pts)
            pygame.draw.polygon(img, OUTLINE, pts, 1)
        elif e.key in ("picture", "discovery"):
            q = square if e.key == "discovery" else square.inflate(-k, -k)
            pygame.draw.rect(img, e.colour, q)
            pygame.draw.rect(img, OUTLINE, q, 1)
        elif e.key == "video":
            self._video_mark(img, cx, cy, k)
        elif e.key in ("victim_found", "victim_missed"):
            self._victim_mark(img, cx, cy, k, e.colour)
        elif e.key == "start":
            pygame.draw.rect(img, mix(FLOOR, e.colour, 0.2), square)
        elif e.key == "zone":
            pygame.draw.rect(img, mix(FLOOR, e.colour, 0.55), square)
        else:  # wall, costly cells: the cell's colour
            pygame.draw.rect(img, e.colour, square)
        if e.key in ("start", "zone", "wall", "costly"):
            pygame.draw.rect(img, DIM, square, 1)

    def _draw_banner(self, surf: pygame.Surface, overlay: Overlay) -> None:
        """The winner banner at the top of the map once the match is finished."""
        story = overlay.story
        b = self.banner = banner(self.model.match.phase, self.model.score, story.victims if story is not None else [])
        if b is None:
            return
        colour = self._colours(b.winner)[0] if b.winner else TEXT
        key = (b, colour, self.layout)
        if self._banner is None or self._banner[0] != key:
            L = self.layout
            pad = L.px(12)
            title, detail = self.text(b.title, L.px(44), colour), self.text(b.detail, L.px(20), TEXT)
            w = max(title.get_width(), detail.get_width()) + 2 * pad
            img = pygame.Surface((w, title.get_height() + detail.get_height() + 2 * pad), 0, 32)
            img.fill(OVER_MAP)
            img.blit(title, ((w - title.get_width()) // 2, pad))
            img.blit(detail, ((w - detail.get_width()) // 2, pad + title.get_height()))
            self._banner = (key, img)
        img = self._banner[1]
        mx, my, mw, _ = self.layout.map
        self._over_map(surf, "banner", img, (mx + (mw - img.get_width()) // 2, my + self.layout.px(12)))

    def _draw_overlay(self, surf: pygame.Surface, geom: MapGeometry, overlay: Overlay) -> None:
        if overlay.selected is None:
            return
        r = self.model.robots.get(overlay.selected)
        if r is None:
            return
        ox, oy = self.tile.origin
        rad = self.robot_radius(geom)
        px, py = geom.cell_centre(r.x, r.y)
        pygame.draw.circle(surf, SELECT, (px - ox, py - oy), rad + max(3, rad // 2), max(2, rad // 4))
        pts = [(px - ox, py - oy)] + [(lambda p: (p[0] - ox, p[1] - oy))(geom.cell_centre(x, y))
                                      for x, y in overlay.points]
        x0, y0, x1, y1 = line_box(pts, 2 * rad + 4)
        self._dirty.append((x0, y0, x1 - x0 + 1, y1 - y0 + 1))
        if len(pts) >= 2:
            draw_lines(surf, PATH, pts, max(2, rad // 3))
        for p in pts[1:]:
            pygame.draw.circle(surf, PATH, p, max(3, rad // 2))

    # ------------------------------------------------------------------ panel and bar
    def _draw_panel(self, surf: pygame.Surface, now: float | None, overlay: Overlay) -> None:
        L = self.layout
        boxes = self.panel_boxes()
        self.boxes = boxes
        m = self.model
        elapsed, remaining = m.match.now(now)
        self._layout_score(boxes["score"])
        if not self._intersects(L.panel):
            return
        clock = clock_line(m.match.phase, elapsed, remaining, replay=m.replay,
                           recording_t=m.clock() if m.replay else None)
        if "ticker" in boxes and overlay.story is not None:
            self.ticker = overlay.story.upto(overlay.story_now, max(1, boxes["ticker"][3] // L.px(18)))
        else:
            self.ticker = []
        shown = (overlay.story.version if overlay.story else -1,
                 tuple((it.id, it.count, it.points) for it in self.ticker))
        key = (m.panel_version, str(clock), shown, tuple(boxes.items()),
               repr(overlay.monitor_data), overlay.info_thing.key if overlay.info_thing else None,
               tuple((k, len(v)) for k, v in overlay.info_pictures.items()),
               repr(overlay.info_thing.info) if overlay.info_thing else None, self._video_tick(overlay, now))
        if self._panel is None or self._panel[0] != key:
            self._panel = (key, self._render_panel(boxes, str(replace(clock, phase=clock.phase.upper())), overlay))
        self._show(surf, "panel", self._panel[1], self._panel[1], L.panel[:2])

    def _layout_score(self, box: Rect) -> None:
        line = self.layout.px(20)
        pad = self.layout.px(8)
        rows = self._score_rows()
        self.score_rows = {row["team"]: (box[0] + pad, box[1] + pad + line * (3 + i), box[2] - 2 * pad, line)
                           for i, row in enumerate(rows)}

    def _score_rows(self) -> list[dict[str, Any]]:
        if self.model.score:
            return sorted(self.model.score, key=lambda r: (r.get("rank", 99), str(r.get("team"))))
        return [{"team": t, "score": 0, "victims": 0, "penalties": 0, "rank": i + 1}
                for i, t in enumerate(self.model.teams())]

    def _render_panel(self, boxes: dict[Any, Rect], clock: str, overlay: Overlay) -> pygame.Surface:
        L = self.layout
        px0, py0, pw, ph = L.panel
        panel = pygame.Surface((pw, ph), 0, 32)
        panel.fill(PANEL_BG)
        size = L.px(20)
        pad = L.px(8)

        def box(rect: Rect) -> pygame.Rect:
            r = pygame.Rect(rect[0] - px0, rect[1] - py0, rect[2], rect[3])
            pygame.draw.rect(panel, BOX_BG, r)
            return r

        def put(s: str, x: int, y: int, colour: RGB = TEXT, sz: int = size, right: int | None = None) -> None:
            t = self.text(s, sz, colour)
            if right is not None:
                x = right - t.get_width()
            panel.blit(t, (x, y))

        m = self.model
        r = box(boxes["score"])
        x0, y = r.x + pad, r.y + pad
        put(m.arena.name if m.arena else "", x0, y, TEXT, L.px(24))
        y += size
        put(clock, x0, y, BROADCAST if m.match.phase in ("paused", "setup") else TEXT)
        y += size
        cols = (r.right - pad - L.px(130), r.right - pad - L.px(60), r.right - pad)
        put("team", x0 + L.px(22), y, DIM)
        for c, head in zip(cols, ("score", "victims", "pen.")):
            put(head, 0, y, DIM, right=c)
        for row in self._score_rows():
            y += size
            team = str(row.get("team"))
            pygame.draw.rect(panel, self._colours(team)[0], (x0, y + 2, L.px(14), size - 6))
            colour = DIM if row.get("disqualified") else TEXT
            put(f"{row.get('rank', '')}. {team}", x0 + L.px(22), y, colour)
            for c, k in zip(cols, ("score", "victims", "penalties")):
                v = row.get(k, 0)
                put(f"{v:g}" if isinstance(v, float) else str(v), 0, y, colour, right=c)
        if "info" in boxes and overlay.info_thing is not None:
            self._render_info(panel, box(boxes["info"]), overlay, put)
        elif "info" in boxes:
            r = box(boxes["info"])
            put(f"{self.view.info}: nothing known", r.x + pad, r.y + pad, DIM)
        for k, rect in boxes.items():
            if isinstance(k, tuple) and k[0] == "monitor":
                self._render_monitor(panel, box(rect), k[1], overlay.monitor_data.get(k[1]), put)
        if "ticker" in boxes:
            self._render_ticker(panel, box(boxes["ticker"]), put)
        return panel

    def _item_colour(self, it: StoryItem) -> RGB:
        """A ticker line's swatch: a find's state colour, else its team's, else its kind's."""
        if it.kind == "find":
            return FIND_COLOURS.get(it.state, FIND_COLOURS["reported"])
        return self._colours(it.team)[0] if it.team else KIND_COLOURS.get(it.kind, DIM)

    def _render_ticker(self, panel: pygame.Surface, r: pygame.Rect, put: Any) -> None:
        """The ticker: what happened, newest first, each line with its match-clock time, a swatch,
        its words (wrapped once) and its points (the web page's ticker, from the same story)."""
        L = self.layout
        pad, size = L.px(8), L.px(18)
        put("what happened", r.x + pad, r.y + L.px(5), DIM, L.px(20))
        y = r.y + L.px(28)
        if not self.ticker:
            put("nothing yet", r.x + pad, y, DIM, size)
            return
        font = self.font(size)
        x_sw = r.x + pad + font.size("00:00 ")[0]
        x_tx = x_sw + L.px(14)
        for it in self.ticker:
            if y + size > r.bottom - L.px(4):
                break
            pts = ""
            if it.points:
                pts = ("+" if it.points > 0 else "\u2212") + number_text(abs(it.points))
            pts_w = font.size(pts)[0] + L.px(6) if pts else 0
            lines = wrap(font, it.text, r.right - pad - pts_w - x_tx)
            put(clock_text(it.c if it.c is not None else it.t), r.x + pad, y, DIM, size)
            pygame.draw.rect(panel, self._item_colour(it), (x_sw, y + 2, L.px(9), size - 6))
            if pts:
                put(pts, 0, y, (110, 220, 120) if it.points > 0 else ERROR, size, right=r.right - pad)
            for i, line in enumerate(lines[:2]):
                if i and y + 2 * size > r.bottom - L.px(4):
                    break
                put(line, x_tx, y, BROADCAST if it.kind in ("broadcast", "phase") else TEXT, size)
                y += size
            y += L.px(3)

    def _render_info(self, panel: pygame.Surface, r: pygame.Rect, overlay: Overlay, put: Any) -> None:
        L = self.layout
        t = overlay.info_thing
        assert t is not None
        pad, size = L.px(8), L.px(18)
        pygame.draw.rect(panel, FIND_COLOURS.get(t.state, DISCOVERY), (r.x, r.y, r.w, L.px(24)))
        put(f"{t.kind} {t.id}  {t.state}", r.x + pad, r.y + L.px(4), OUTLINE, L.px(20))
        put("x", 0, r.y + L.px(4), OUTLINE, L.px(20), right=r.right - pad)
        y = r.y + L.px(30)
        info = dict(t.info)
        lines = [" ".join(f"{k}: {info.pop(k)}" for k in ("kind", "team", "tag") if k in info),
                 f"at ({t.x:g}, {t.y:g})"]
        lines += [f"{k}: {info.pop(k)}" for k in ("message", "state", "evidence") if k in info]
        lines += [f"{k}: {v}" for k, v in info.items() if k not in ("id", "png", "x", "y")]
        for line in lines:
            if y > r.bottom - L.px(100):
                break
            put(line[:60], r.x + pad, y, TEXT, size)
            y += size
        x = r.x + pad
        th = L.px(80)
        for pid in t.pictures()[:4]:
            got = overlay.info_pictures.get(pid)
            if isinstance(got, str):
                put(f"picture {pid}: {got}"[:60], r.x + pad, y, ERROR, size)
                y += size
                continue
            img = self._picture(pid, got)
            if img is None:
                continue
            w = max(1, rnd(img.get_width() * th / max(1, img.get_height())))
            if x + w > r.right:
                break
            panel.blit(pygame.transform.scale(img, (w, th)), (x, r.bottom - th - pad))
            x += w + pad
        self._render_video(panel, r, overlay, put)

    def _video_mark(self, surf: pygame.Surface, cx: int, cy: int, k: int) -> None:
        """A video on the map: a play triangle in the legend's video colour (the page's)."""
        q = max(3, k * 3 // 4)
        pts = [(cx - q * 3 // 5, cy - q), (cx + q, cy), (cx - q * 3 // 5, cy + q)]
        pygame.draw.polygon(surf, VIDEO, pts)
        pygame.draw.polygon(surf, OUTLINE, pts, 1)

    def _video_tick(self, overlay: Overlay, now: float | None) -> int | None:
        """The frame of the video in the info box to show now (the panel is drawn again when it
        changes: the wall plays the video at its frame rate); None without a video."""
        t = overlay.info_thing
        frames = overlay.info_videos.get(t.videos()[0]) if t is not None and t.videos() else None
        if not isinstance(frames, list) or not frames:
            return None
        self._video_frame = int((now or 0.0) * VIDEO_FPS) % len(frames)
        return self._video_frame

    def _render_video(self, panel: pygame.Surface, r: pygame.Rect, overlay: Overlay, put: Any) -> None:
        """A video in the info box, playing (frame :attr:`_video_frame`), or why it cannot be shown."""
        t = overlay.info_thing
        if t is None or not t.videos():
            return
        L = self.layout
        pad, size = L.px(8), L.px(18)
        vid = t.videos()[0]
        got = overlay.info_videos.get(vid)
        if isinstance(got, str):
            put(f"video {vid}: {got}"[:60], r.x + pad, r.bottom - size - pad, ERROR, size)
            return
        if not got:
            return
        frame = got[min(self._video_frame, len(got) - 1)]
        img = pygame.surfarray.make_surface(frame.swapaxes(0, 1))
        th = L.px(120)
        w = max(1, rnd(img.get_width() * th / max(1, img.get_height())))
        panel.blit(pygame.transform.scale(img, (min(w, r.w - 2 * pad), th)), (r.x + pad, r.bottom - th - pad))

    def _picture(self, pid: int, png: bytes | None) -> pygame.Surface | None:
        if pid not in self._pictures and png:
            try:
                self._pictures[pid] = pygame.image.load(io.BytesIO(png), "p.png")
            except pygame.error:
                self._pictures[pid] = None
        return self._pictures.get(pid)

    def _render_monitor(self, panel: pygame.Surface, r: pygame.Rect, tag: int, data: dict[str, Any] | str | None,
                        put: Any) -> None:
        L = self.layout
        pad, size = L.px(8), L.px(18)
        robot = self.model.robots.get(tag)
        team = robot.team if robot else (data.get("team") if isinstance(data, dict) else None)
        pygame.draw.rect(panel, self._colours(team)[0], (r.x, r.y, r.w, L.px(24)))
        put(f"robot {tag}  {team or ''}", r.x + pad, r.y + L.px(4), OUTLINE, L.px(20))
        put("x", 0, r.y + L.px(4), OUTLINE, L.px(20), right=r.right - pad)
        y = r.y + L.px(30)
        if data is None:
            put("asking the core...", r.x + pad, y, DIM, size)
            return
        if isinstance(data, str):
            put(data[:60], r.x + pad, y, ERROR, size)
            return
        task = data.get("task")
        lines = [f"status: {data.get('status')}   ({data.get('x', 0):.1f}, {data.get('y', 0):.1f})  "
                 f"{data.get('heading', 0):.0f}°",
                 "task: " + (f"{task['name']} #{task.get('task_id')} {task.get('args', '')}" if task else "none")
                 + f"   queued: {data.get('queue', 0)}"]
        for d in list(data.get("done") or [])[-3:][::-1]:
            lines.append(f"done: {d.get('name')} #{d.get('task_id')} {'ok' if d.get('ok') else 'failed'}"
                         f" {d.get('status', '')}")
        lines.append("can: " + ", ".join(a.get("name", "?") for a in data.get("advertised") or []))
        for k, v in sorted((data.get("sensors") or {}).items()):
            lines.append(f"{k}: {v}")
        for s in lines:
            if y > r.bottom - size:
                break
            put(s[:64], r.x + pad, y, TEXT, size)
            y += size

    def _draw_bar(self, surf: pygame.Surface, now: float | None, overlay: Overlay) -> None:
        L = self.layout
        if not self._intersects(L.bar):
            return
        msgs = self.model.visible_messages(now)
        last = msgs[-1] if msgs else None
        if self.model.storage is not None:  # a storage fault stays on the bar while it lasts
            last = Message("STORAGE FAULT: " + self.model.storage, "error", now or 0.0)
        key = (overlay.hint, last.text if last else "", last.level if last else "")
        if self._bar is None or self._bar[0] != key:
            bar = pygame.Surface(L.bar[2:], 0, 32)
            bar.fill(PANEL_BG)
            size = L.px(22)
            y = (L.bar[3] - size) // 2 + L.px(2)
            if last is not None:
                colour = {"error": ERROR, "broadcast": BROADCAST}.get(last.level, TEXT)
                bar.blit(self.text(last.text[:160], size, colour), (L.px(10), y))
            if overlay.hint:
                t = self.text(overlay.hint, size, DIM)
                bar.blit(t, (L.bar[2] - t.get_width() - L.px(10), y))
            self._bar = (key, bar)
        self._show(surf, "bar", self._bar[1], self._bar[1], L.bar[:2])

"""The simulated robot camera: a small egocentric top-down picture encoded as PNG.

The picture shows what lies ahead of the robot (forward is up, the robot sits at the
bottom centre): floor, walls, surface zones, other robots in their team colour and
victims. Cells outside the field of view or hidden behind walls are drawn dimmed and
show no robots or victims. PNGs are written with :mod:`zlib` and :mod:`struct` only.
"""
from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass

import numpy as np

__all__ = ["CameraView", "encode_png", "decode_png_size", "render_view", "ZONE_COLOURS",
           "WIDTH", "HEIGHT"]

#: Picture size in pixels.
WIDTH, HEIGHT = 96, 64

FLOOR = np.array([205, 200, 190], dtype=np.uint8)
WALL = np.array([60, 60, 70], dtype=np.uint8)
OUTSIDE = np.array([0, 0, 0], dtype=np.uint8)
VICTIM = np.array([255, 120, 0], dtype=np.uint8)
#: Floor colour of surface zone kinds (others use a neutral tint).
ZONE_COLOURS = {
    "rubble": (150, 120, 90), "water": (90, 140, 220), "stairs": (150, 100, 170),
    "drop": (120, 60, 120), "hole": (120, 60, 120), "fire": (230, 90, 60),
}


@dataclass
class CameraView:
    """What the renderer needs about the world: ground-truth grids and objects."""

    walls: np.ndarray                  # bool (h, w)
    zone_rgb: np.ndarray               # uint8 (h, w, 3) floor colour per cell
    robots: list[tuple[float, float, tuple[int, int, int]]]  # other robots: x, y, rgb
    victims: list[tuple[float, float]]


def encode_png(rgb: np.ndarray) -> bytes:
    """Encode an (h, w, 3) uint8 array as an 8-bit RGB PNG."""
    a = np.ascontiguousarray(rgb, dtype=np.uint8)
    h, w, c = a.shape
    if c != 3:
        raise ValueError("encode_png expects an (h, w, 3) array")
    raw = np.concatenate([np.zeros((h, 1), dtype=np.uint8), a.reshape(h, w * 3)], axis=1).tobytes()

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    return (b"\x89PNG\r\n\x1a\n"
            + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw, 6))
            + chunk(b"IEND", b""))


def decode_png_size(data: bytes) -> tuple[int, int]:
    """(width, height) from a PNG's IHDR; ValueError if ``data`` is not a PNG."""
    if data[:8] != b"\x89PNG\r\n\x1a\n" or data[12:16] != b"IHDR":
        raise ValueError("not a PNG")
    w, h = struct.unpack(">II", data[16:24])
    return w, h


def line_of_sight(walls: np.ndarray, x0: float, y0: float, x1: np.ndarray, y1: np.ndarray,
                  step: float = 0.2) -> np.ndarray:
    """True where the straight line from (x0, y0) to each (x1, y1) crosses no wall cell
    (the end cell itself is not tested)."""
    x1 = np.asarray(x1, dtype=np.float64)
    y1 = np.asarray(y1, dtype=np.float64)
    h, w = walls.shape
    dist = np.hypot(x1 - x0, y1 - y0)
    n = int(np.ceil(dist.max() / step)) + 1 if dist.size else 0
    ok = np.ones(x1.shape, dtype=bool)
    ex = np.floor(x1 + 0.5)
    ey = np.floor(y1 + 0.5)
    for k in range(1, n):
        f = np.minimum(k * step / np.maximum(dist, 1e-9), 1.0)
        px = np.floor(x0 + (x1 - x0) * f + 0.5)
        py = np.floor(y0 + (y1 - y0) * f + 0.5)
        end = (px == ex) & (py == ey)
        inside = (px >= 0) & (px < w) & (py >= 0) & (py < h)
        blocked = np.ones(px.shape, dtype=bool)
        blocked[inside] = walls[py[inside].astype(np.int64), px[inside].astype(np.int64)]
        ok &= end | ~blocked
    return ok


def render_view(view: CameraView, x: float, y: float, heading_deg: float, fov_deg: float,
                range_cells: float, width: int = WIDTH, height: int = HEIGHT) -> np.ndarray:
    """Render the egocentric picture of a robot at (x, y, heading) as (height, width, 3) uint8."""
    walls = view.walls
    h, w = walls.shape
    scale = height / range_cells                      # pixels per cell
    hr = np.radians(heading_deg)
    f = np.array([np.cos(hr), np.sin(hr)])            # forward unit vector
    r = np.array([-np.sin(hr), np.cos(hr)])           # right unit vector (heading + 90°)
    vv, uu = np.mgrid[0:height, 0:width].astype(np.float64)
    fwd = (height - 0.5 - vv) / scale
    lat = (uu + 0.5 - width / 2) / scale
    wx = x + fwd * f[0] + lat * r[0]
    wy = y + fwd * f[1] + lat * r[1]
    cx = np.floor(wx + 0.5).astype(np.int64)
    cy = np.floor(wy + 0.5).astype(np.int64)
    inside = (cx >= 0) & (cx < w) & (cy >= 0) & (cy < h)
    cxc, cyc = np.clip(cx, 0, w - 1), np.clip(cy, 0, h - 1)
    img = view.zone_rgb[cyc, cxc].copy()
    wall = walls[cyc, cxc] & inside
    img[wall] = WALL
    img[~inside] = OUTSIDE
    # Field of view and line of sight.
    dist = np.hypot(fwd, lat)
    ang = np.degrees(np.abs(np.arctan2(lat, fwd)))
    in_fov = (dist <= range_cells) & (ang <= fov_deg / 2)
    visible = in_fov.copy()
    visible[in_fov] = line_of_sight(walls, x, y, wx[in_fov], wy[in_fov])
    # Objects: disks, only where visible.
    for ox, oy, rgb in view.robots:
        m = ((wx - ox) ** 2 + (wy - oy) ** 2 <= 0.4 ** 2) & visible
        img[m] = rgb
    for ox, oy in view.victims:
        d2 = (wx - ox) ** 2 + (wy - oy) ** 2
        img[(d2 <= 0.35 ** 2) & visible] = VICTIM
        img[(d2 <= 0.12 ** 2) & visible] = (255, 255, 255)
    img[~visible] = (img[~visible].astype(np.uint16) * 2 // 7).astype(np.uint8)
    # The robot itself: a small marker at the bottom centre.
    img[height - 3:, width // 2 - 2: width // 2 + 2] = (255, 255, 255)
    return img

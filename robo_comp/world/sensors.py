"""Simulated ultrasonic range sensors (thesis appendix B) and the grid ray caster behind them.

The thesis robot carried four SRF04 sensors: front, left, right and one pointing down
ahead of the robot to see edges such as stairs; they read about 10..300 cm. Here every
reading is computed for all robots at once with :func:`cast_rays`, an exact grid
traversal (Amanatides & Woo) vectorised with numpy over the rays.

Conventions: positions are in cells with cell centres at integer coordinates (cell
``(i, j)`` covers ``[i-0.5, i+0.5) × [j-0.5, j+0.5)``); headings are degrees with 0 = +x
(east) and 90 = +y (south, down the screen), so "left" is ``heading - 90`` and "right"
``heading + 90``. A reading is the distance in cm from the robot's centre to the first
blocked cell (walls, the map edge, other robots); ``None`` (``nan`` in arrays) means no
echo within ``max_range``; readings below ``min_range`` read as ``min_range``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robo_comp.world.scenario import SensorConfig

__all__ = ["cast_rays", "RangeReadings", "sense_ranges", "SENSOR_OFFSETS", "DOWN_LOOKAHEAD"]

#: Direction of each horizontal sensor relative to the heading, in degrees.
SENSOR_OFFSETS = {"front": 0.0, "left": -90.0, "right": 90.0}
#: How far ahead of the robot's centre (cells) the downward sensor looks at the floor.
DOWN_LOOKAHEAD = 0.75


_KERNEL: list = []          # [compiled kernel or None] once tried
#: Rays from which the compiled kernel is used (below, numpy's loop costs less than the call).
COMPILED_FROM = 16


def warm_up() -> None:
    """Compile (or load from the disk cache) the ray-casting kernel now, not during a report."""
    one = np.zeros(1)
    cast_rays(np.zeros((2, 2), dtype=bool), one, one, one, 1.0, compiled=True)


def _compiled_kernel():  # pragma: no cover - exercised when numba is installed
    """The numba ray-casting kernel, compiled (and cached on disk) on first use; None if
    numba is unavailable. Numba is imported lazily so importing the arena stays cheap."""
    if _KERNEL:
        return _KERNEL[0]
    try:
        from numba import njit
    except Exception:
        _KERNEL.append(None)
        return None

    @njit(cache=True, nogil=True)
    def kernel(blocked, x, y, ang, max_dist, out):
        h, w = blocked.shape
        for i in range(x.shape[0]):
            u = x[i] + 0.5
            v = y[i] + 0.5
            dx = np.cos(ang[i])
            dy = np.sin(ang[i])
            cx = int(np.floor(u))
            cy = int(np.floor(v))
            if abs(dx) > 1e-12:
                tdx = abs(1.0 / dx)
                sx = 1 if dx > 0 else -1
                tmx = (cx + 1 - u) * tdx if dx > 0 else (u - cx) * tdx
            else:
                tdx = np.inf
                sx = 1
                tmx = np.inf
            if abs(dy) > 1e-12:
                tdy = abs(1.0 / dy)
                sy = 1 if dy > 0 else -1
                tmy = (cy + 1 - v) * tdy if dy > 0 else (v - cy) * tdy
            else:
                tdy = np.inf
                sy = 1
                tmy = np.inf
            res = np.inf
            while True:
                if tmx < tmy:
                    t = tmx
                    cx += sx
                    tmx += tdx
                else:
                    t = tmy
                    cy += sy
                    tmy += tdy
                if t > max_dist:
                    break
                if cx < 0 or cx >= w or cy < 0 or cy >= h or blocked[cy, cx]:
                    res = t
                    break
            out[i] = res

    _KERNEL.append(kernel)
    return kernel


def cast_rays(blocked: np.ndarray, x: np.ndarray, y: np.ndarray, angle: np.ndarray,
              max_dist: float, *, compiled: bool | None = None) -> np.ndarray:
    """Distance (cells) from each origin ``(x, y)`` along ``angle`` (radians) to the first
    blocked cell boundary, ``inf`` if none within ``max_dist``; the map edge blocks.

    The origin's own cell is never tested, so a robot does not see itself. All arrays are
    1-D of the same length. Uses a numba kernel when numba is installed and there are
    enough rays to pay for it (``compiled`` forces the choice); otherwise a numpy loop
    over cell crossings.
    """
    n = len(x)
    use = compiled if compiled is not None else n >= COMPILED_FROM
    if use and n:
        k = _compiled_kernel()
        if k is not None:
            out = np.empty(n)
            k(np.ascontiguousarray(blocked, dtype=np.bool_), np.ascontiguousarray(x, dtype=np.float64),
              np.ascontiguousarray(y, dtype=np.float64), np.ascontiguousarray(angle, dtype=np.float64),
              float(max_dist), out)
            return out
    return _cast_rays_numpy(blocked, x, y, angle, max_dist)


def _cast_rays_numpy(blocked: np.ndarray, x: np.ndarray, y: np.ndarray, angle: np.ndarray,
                     max_dist: float) -> np.ndarray:
    """The numpy implementation of :func:`cast_rays`."""
    h, w = blocked.shape
    n = len(x)
    out = np.full(n, np.inf)
    if n == 0:
        return out
    u = np.asarray(x, dtype=np.float64) + 0.5
    v = np.asarray(y, dtype=np.float64) + 0.5
    dx = np.cos(angle)
    dy = np.sin(angle)
    cx = np.floor(u).astype(np.int64)
    cy = np.floor(v).astype(np.int64)
    with np.errstate(divide="ignore", invalid="ignore"):
        sx = np.where(dx > 0, 1, -1)
        sy = np.where(dy > 0, 1, -1)
        tdx = np.where(np.abs(dx) > 1e-12, np.abs(1.0 / dx), np.inf)
        tdy = np.where(np.abs(dy) > 1e-12, np.abs(1.0 / dy), np.inf)
        tmx = np.where(dx > 0, (cx + 1 - u) * tdx, (u - cx) * tdx)
        tmy = np.where(dy > 0, (cy + 1 - v) * tdy, (v - cy) * tdy)
    tmx = np.where(np.isfinite(tdx), tmx, np.inf)
    tmy = np.where(np.isfinite(tdy), tmy, np.inf)
    idx = np.arange(n)
    flat = blocked.reshape(-1)
    max_iter = int(2 * (max_dist + 2)) + 2
    for _ in range(max_iter):
        if idx.size == 0:
            break
        stepx = tmx < tmy
        t = np.where(stepx, tmx, tmy)
        cx = np.where(stepx, cx + sx, cx)
        cy = np.where(stepx, cy, cy + sy)
        tmx = np.where(stepx, tmx + tdx, tmx)
        tmy = np.where(stepx, tmy, tmy + tdy)
        far = t > max_dist
        outside = (cx < 0) | (cx >= w) | (cy < 0) | (cy >= h)
        hit = ~far & (outside | flat[np.clip(cy, 0, h - 1) * w + np.clip(cx, 0, w - 1)])
        out[idx[hit]] = t[hit]
        keep = ~(far | hit)
        if not keep.all():
            idx, cx, cy, tmx, tmy, tdx, tdy, sx, sy = (
                a[keep] for a in (idx, cx, cy, tmx, tmy, tdx, tdy, sx, sy))
    return out


@dataclass
class RangeReadings:
    """Readings of many robots at once, in cm (``nan`` = no echo within range)."""

    front: np.ndarray
    left: np.ndarray
    right: np.ndarray
    down: np.ndarray

    def row(self, i: int) -> dict[str, float | None]:
        """The readings of robot ``i`` as a plain dict (``None`` for no echo)."""
        out: dict[str, float | None] = {}
        for k in ("front", "left", "right", "down"):
            v = float(getattr(self, k)[i])
            out[k] = None if v != v else round(v, 2)
        return out


def sense_ranges(blocked: np.ndarray, drops: np.ndarray, x: np.ndarray, y: np.ndarray,
                 heading_deg: np.ndarray, cfg: SensorConfig, cell_size: float,
                 rng: np.random.Generator) -> RangeReadings:
    """Front/left/right/down readings for robots at ``(x, y, heading_deg)``.

    ``blocked`` is the obstacle grid (walls plus cells of other robots), ``drops`` the
    cells the downward sensor sees as an edge. Gaussian noise of σ ``cfg.noise`` cm is
    added, then readings are clipped to ``min_range`` and beyond ``max_range`` become
    ``nan``.
    """
    n = len(x)
    max_cells = cfg.max_range / cell_size
    xs = np.tile(np.asarray(x, dtype=np.float64), 3)
    ys = np.tile(np.asarray(y, dtype=np.float64), 3)
    ang = np.concatenate([np.radians(np.asarray(heading_deg, dtype=np.float64) + off)
                          for off in SENSOR_OFFSETS.values()])
    d = cast_rays(blocked, xs, ys, ang, max_cells + 3 * cfg.noise / cell_size + 1e-9) * cell_size
    if cfg.noise > 0:
        d = d + rng.normal(0.0, cfg.noise, d.shape)
    d = np.where(d > cfg.max_range, np.nan, np.maximum(d, cfg.min_range))
    # Down sensor: the floor a little ahead of the robot.
    hr = np.radians(np.asarray(heading_deg, dtype=np.float64))
    px = np.floor(np.asarray(x) + DOWN_LOOKAHEAD * np.cos(hr) + 0.5).astype(np.int64)
    py = np.floor(np.asarray(y) + DOWN_LOOKAHEAD * np.sin(hr) + 0.5).astype(np.int64)
    h, w = drops.shape
    inside = (px >= 0) & (px < w) & (py >= 0) & (py < h)
    drop = np.zeros(n, dtype=bool)
    drop[inside] = drops[py[inside], px[inside]]
    down = np.where(drop, cfg.floor + cfg.drop_depth, cfg.floor).astype(np.float64)
    if cfg.noise > 0:
        down = down + rng.normal(0.0, cfg.noise, n)
    down = np.where(down > cfg.max_range, np.nan, np.maximum(down, cfg.min_range))
    return RangeReadings(front=d[:n], left=d[n:2 * n], right=d[2 * n:], down=down)

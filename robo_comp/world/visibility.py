"""What a camera at a pose can see: victims in the field of view, in range, in line of sight."""
from __future__ import annotations

import numpy as np

from robo_comp.world.camera import line_of_sight


def in_view(walls: np.ndarray, points: list[tuple[float, float]], x: float, y: float, heading: float,
            fov: float, rng: float) -> list[bool]:
    """For each point, True when a camera at (x, y) facing ``heading`` degrees (clockwise
    from east, y down) with field of view ``fov`` degrees and range ``rng`` cells sees it."""
    if not points:
        return []
    px = np.array([p[0] for p in points], dtype=np.float64)
    py = np.array([p[1] for p in points], dtype=np.float64)
    dist = np.hypot(px - x, py - y)
    ang = np.abs((np.degrees(np.arctan2(py - y, px - x)) - heading + 180.0) % 360.0 - 180.0)
    cand = (dist <= rng) & ((ang <= fov / 2) | (dist < 0.5))
    if cand.any():
        los = line_of_sight(walls, x, y, px[cand], py[cand])
        cand[np.flatnonzero(cand)[~los]] = False
    return cand.tolist()

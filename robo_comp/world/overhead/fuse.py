"""Several cameras, one pose per robot: sightings weighted by how well each camera is calibrated."""
from __future__ import annotations

import math
from dataclasses import dataclass

#: The smallest σ (cells) a single sighting is given, however good its camera's calibration.
MIN_SIGMA = 0.03


@dataclass(frozen=True)
class Sighting:
    """A robot marker seen by one camera, on the floor, with that camera's uncertainty σ (cells)."""

    x: float
    y: float
    heading: float
    sigma: float
    camera: int


@dataclass(frozen=True)
class FusedPose:
    """One robot's pose from every camera that saw it."""

    x: float
    y: float
    heading: float
    sigma: float
    cameras: tuple[int, ...]


def fuse(sightings: list[Sighting]) -> FusedPose:
    """Inverse-variance weighted mean of the positions, weighted circular mean of the headings;
    the fused σ is that of the weighted mean (smaller than any one camera's)."""
    if not sightings:
        raise ValueError("nothing to fuse")
    w = [1.0 / max(s.sigma, MIN_SIGMA) ** 2 for s in sightings]
    total = sum(w)
    x = sum(wi * s.x for wi, s in zip(w, sightings)) / total
    y = sum(wi * s.y for wi, s in zip(w, sightings)) / total
    c = sum(wi * math.cos(math.radians(s.heading)) for wi, s in zip(w, sightings))
    s_ = sum(wi * math.sin(math.radians(s.heading)) for wi, s in zip(w, sightings))
    return FusedPose(x, y, math.degrees(math.atan2(s_, c)) % 360.0, math.sqrt(1.0 / total),
                     tuple(sorted({s.camera for s in sightings})))

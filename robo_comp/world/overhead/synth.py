"""Synthetic overhead frames of a simulated arena, with the true poses known.

A :class:`SyntheticCamera` looks at the floor from above and at an angle: the floor (cells) maps
to its image (pixels) through a homography, as it does for a real camera over a flat arena. It
draws the walls, the floor markers and every robot's marker (upper edge towards the robot's
front, on a white robot top), then degrades the frame as a cheap webcam would
(:class:`Degradation`: blur, sensor noise, uneven light, markers partly hidden).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from robo_comp.world.overhead.markers import marker_image

#: Frame size of the synthetic cameras (pixels).
SIZE = (1280, 720)


@dataclass(frozen=True)
class Degradation:
    """What spoils a frame: Gaussian ``blur`` (σ, pixels), sensor ``noise`` (σ, grey levels),
    uneven ``light`` (0: even; 0.6: the dark side gets 40 % of the light), ``occlude``: the
    fraction of robot markers with a quarter hidden (an arm, a cable)."""

    blur: float = 0.0
    noise: float = 0.0
    light: float = 0.0
    occlude: float = 0.0
    seed: int = 0


#: The conditions the bench and the tests use, by name.
CONDITIONS: dict[str, Degradation] = {
    "clean": Degradation(),
    "blur": Degradation(blur=1.2),
    "noise": Degradation(noise=12.0),
    "uneven light": Degradation(light=0.6),
    "occlusion": Degradation(occlude=0.3),
    "all": Degradation(blur=0.8, noise=8.0, light=0.4, occlude=0.15),
}


class SyntheticCamera:
    """A camera over the cells ``view`` = (x0, y0, x1, y1) of the floor: the view's far edge
    (small y) appears narrower than its near edge (perspective)."""

    def __init__(self, view: tuple[float, float, float, float], size: tuple[int, int] = SIZE,
                 tilt: float = 0.12) -> None:
        self.size = size
        self.view = view
        w, h = size
        x0, y0, x1, y1 = view
        floor = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float32)
        inset = tilt * w
        img = np.array([[inset, 0.04 * h], [w - inset, 0.04 * h], [w - 1, 0.98 * h], [0, 0.98 * h]],
                       dtype=np.float32)
        #: floor (cells) → image (pixels), the truth a calibration estimates
        self.to_image = cv2.getPerspectiveTransform(floor, img)

    def project(self, pts: np.ndarray) -> np.ndarray:
        """Floor points (N×2 cells) → image points (N×2 pixels)."""
        return cv2.perspectiveTransform(np.asarray(pts, np.float64).reshape(-1, 1, 2), self.to_image).reshape(-1, 2)

    def render(self, walls: np.ndarray, robots: list[tuple[int, float, float, float]],
               floor: dict[int, tuple[float, float]], marker_cells: float = 0.8,
               degrade: Degradation = Degradation()) -> np.ndarray:
        """A grayscale frame: ``walls`` (bool [y, x]), ``robots`` as (marker, x, y, heading) true
        poses, ``floor`` markers at their cells, robot markers ``marker_cells`` wide."""
        w, h = self.size
        rng = np.random.default_rng(degrade.seed)
        ppc = 8  # pixels per cell of the top-down floor picture that is warped into the view
        top = cv2.resize(np.where(walls, 70, 205).astype(np.uint8), (walls.shape[1] * ppc, walls.shape[0] * ppc), interpolation=cv2.INTER_NEAREST)
        scale = np.diag([1.0 / ppc, 1.0 / ppc, 1.0])
        frame = cv2.warpPerspective(top, self.to_image @ scale, (w, h), borderValue=30)
        for m, (x, y) in floor.items():
            self._paste(frame, m, x, y, 270.0, 0.9)
        hidden = rng.random(len(robots)) < degrade.occlude
        for k, (m, x, y, heading) in enumerate(robots):
            self._paste(frame, m, x, y, heading, marker_cells, white_cells=marker_cells * 1.25)
            if hidden[k]:  # a quarter of the marker behind something grey
                c = self._corners(x, y, heading, marker_cells)
                quarter = np.array([c[0], (c[0] + c[1]) / 2, (c[0] + c[1] + c[2] + c[3]) / 4, (c[0] + c[3]) / 2])
                cv2.fillConvexPoly(frame, self.project(quarter).round().astype(np.int32), 120)
        out: npt.NDArray[np.float32] = frame.astype(np.float32)
        if degrade.light:
            ramp = np.linspace(1.0 - degrade.light, 1.0, w, dtype=np.float32)
            out *= ramp[None, :]
        if degrade.blur:
            out = cv2.GaussianBlur(out, (0, 0), degrade.blur).astype(np.float32, copy=False)  # stays float32
        if degrade.noise:
            out += rng.normal(0.0, degrade.noise, out.shape).astype(np.float32)
        return np.clip(out, 0, 255).astype(np.uint8)

    @staticmethod
    def _corners(x: float, y: float, heading: float, side: float) -> np.ndarray:
        """The marker's corners on the floor: top-left, top-right, bottom-right, bottom-left, its
        upper edge towards ``heading``."""
        a = math.radians(heading)
        up = np.array([math.cos(a), math.sin(a)])
        right = np.array([-up[1], up[0]])
        c = np.array([x, y])
        s = side / 2
        return np.array([c + up * s - right * s, c + up * s + right * s, c - up * s + right * s, c - up * s - right * s])

    def _paste(self, frame: np.ndarray, marker: int, x: float, y: float, heading: float, side: float,
               white_cells: float | None = None) -> None:
        if white_cells:  # the robot's white top around its marker (the marker's quiet zone)
            cv2.fillConvexPoly(frame, self.project(self._corners(x, y, heading, white_cells)).round().astype(np.int32), 250)
        dst = self.project(self._corners(x, y, heading, side)).astype(np.float32)
        x0, y0 = np.floor(dst.min(axis=0)).astype(int) - 1
        x1, y1 = np.ceil(dst.max(axis=0)).astype(int) + 1
        fh, fw = frame.shape
        if x1 <= 0 or y1 <= 0 or x0 >= fw or y0 >= fh:
            return
        px = 64
        src = np.array([[0, 0], [px, 0], [px, px], [0, px]], dtype=np.float32)
        shift = np.array([[1, 0, -x0], [0, 1, -y0], [0, 0, 1]], dtype=np.float64)
        m = shift @ cv2.getPerspectiveTransform(src, dst)
        pw, ph = x1 - x0, y1 - y0
        patch = cv2.warpPerspective(marker_image(marker, px), m, (pw, ph), flags=cv2.INTER_LINEAR)
        mask = cv2.warpPerspective(np.full((px, px), 255, np.uint8), m, (pw, ph), flags=cv2.INTER_LINEAR)
        fx0, fy0, fx1, fy1 = max(x0, 0), max(y0, 0), min(x1, fw), min(y1, fh)
        region = frame[fy0:fy1, fx0:fx1]
        p = patch[fy0 - y0:fy1 - y0, fx0 - x0:fx1 - x0].astype(np.float32)
        a = mask[fy0 - y0:fy1 - y0, fx0 - x0:fx1 - x0].astype(np.float32) / 255.0
        region[:] = (a * p + (1 - a) * region).astype(np.uint8)


def cameras_for(width: int, height: int, count: int = 1) -> list[SyntheticCamera]:
    """``count`` cameras covering a ``width`` × ``height`` arena side by side, each view overlapping
    its neighbour's by a fifth (with one camera: the whole arena and a cell of margin)."""
    if count == 1:
        return [SyntheticCamera((-1.0, -1.0, width + 0.0, height + 0.0))]
    span = width / count
    pad = span / 5
    return [SyntheticCamera((max(-1.0, i * span - pad), -1.0, min(width + 0.0, (i + 1) * span + pad), height + 0.0))
            for i in range(count)]


def floor_markers(width: int, height: int, first: int = 200) -> dict[int, tuple[float, float]]:
    """Floor markers for a ``width`` × ``height`` arena: a grid of ids ``first``.. every few cells
    along the walls and through the middle, so that every camera view holds four or more."""
    xs = np.linspace(0, width - 1, max(3, width // 4)).round().tolist()
    ys = np.linspace(0, height - 1, 3).round().tolist()
    out: dict[int, tuple[float, float]] = {}
    for j, y in enumerate(ys):
        for i, x in enumerate(xs):
            out[first + len(out)] = (float(x), float(y))
    return out

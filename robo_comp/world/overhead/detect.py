"""Frames → marker corners → robot poses in arena cells.

A robot's marker lies flat on its top with the marker's upper edge towards the robot's front:
the pose is the marker's centre on the floor and the direction from its lower edge to its upper
edge (degrees, 0 = +x, 90 = +y, as the arena counts them).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from robo_comp.world.overhead.markers import dictionary


@dataclass(frozen=True)
class MarkerPose:
    """One marker seen in one frame, mapped onto the floor."""

    marker: int
    x: float
    y: float
    heading: float
    #: the marker's side on the floor, in cells (a check: a misdetection has an odd size)
    side: float
    #: the marker's centre in the image (pixels)
    u: float
    v: float


class Detector:
    """OpenCV's ArUco detector for :data:`~robo_comp.world.overhead.markers.DICTIONARY`."""

    def __init__(self) -> None:
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
        # Markers on robots are 20-60 pixels wide in a 1280x720 frame: two threshold windows and
        # no candidates smaller than that keep a noisy frame's many false candidates out.
        params.adaptiveThreshWinSizeMin = 7
        params.adaptiveThreshWinSizeMax = 17
        params.adaptiveThreshWinSizeStep = 10
        params.minMarkerPerimeterRate = 0.05
        self._det = cv2.aruco.ArucoDetector(dictionary(), params)

    def detect(self, frame: np.ndarray) -> dict[int, np.ndarray]:
        """Marker id → its 4 corners in pixels (float32, 4×2: top-left, top-right, bottom-right,
        bottom-left of the marker as printed). A marker seen twice keeps its first sighting."""
        gray = frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        # a light blur first: sensor noise otherwise makes thousands of candidate squares
        corners, ids, _ = self._det.detectMarkers(cv2.GaussianBlur(gray, (3, 3), 0))
        out: dict[int, np.ndarray] = {}
        if ids is None:
            return out
        for c, i in zip(corners, ids.reshape(-1).tolist()):
            out.setdefault(int(i), c.reshape(4, 2).astype(np.float32))
        return out


def to_floor(homography: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Image points (N×2 pixels) → floor points (N×2 cells) through ``homography``."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 1, 2)
    return cv2.perspectiveTransform(pts, homography).reshape(-1, 2)


def marker_pose(marker: int, corners: np.ndarray, homography: np.ndarray) -> MarkerPose:
    """The floor pose of one marker from its image corners."""
    f = to_floor(homography, corners)
    centre = f.mean(axis=0)
    up = (f[0] + f[1]) / 2 - (f[3] + f[2]) / 2
    side = float(np.mean(np.linalg.norm(f - np.roll(f, 1, axis=0), axis=1)))
    u, v = corners.mean(axis=0).tolist()
    return MarkerPose(marker, float(centre[0]), float(centre[1]),
                      math.degrees(math.atan2(up[1], up[0])) % 360.0, side, u, v)


def poses(found: dict[int, np.ndarray], homography: np.ndarray) -> dict[int, MarkerPose]:
    """:func:`marker_pose` of every detected marker."""
    return {m: marker_pose(m, c, homography) for m, c in found.items()}

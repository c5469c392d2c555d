"""Calibration: floor markers at known cells give the image-to-floor homography of one camera.

Four floor markers or more must be in view (five or more give a reprojection error that means
something: with four the homography fits them exactly). A camera that moves after calibration
is noticed: its floor markers drift away from the cells the calibration put them on
(:func:`drift`). Lens distortion (wide-angle webcams) is taken out first when the camera's
intrinsics were measured from checkerboard views (:func:`calibrate_intrinsics`).
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from robo_comp.errors import FieldError
from robo_comp.world.overhead.detect import to_floor

#: Drift (cells) of the floor markers beyond which a camera is taken to have moved.
MOVED_CELLS = 0.3


@dataclass
class Calibration:
    """One camera's calibration: image (pixels) → floor (cells)."""

    homography: np.ndarray
    #: root-mean-square distance (cells) between the floor markers' known cells and where the
    #: homography puts their image centres
    error_cells: float
    image_size: tuple[int, int]
    #: floor markers used (id → image centre at calibration time, pixels)
    reference: dict[int, tuple[float, float]]
    camera_matrix: np.ndarray | None = None
    distortion: np.ndarray | None = None

    def undistort(self, frame: np.ndarray) -> np.ndarray:
        """``frame`` without lens distortion (unchanged when no intrinsics were measured)."""
        if self.camera_matrix is None or self.distortion is None:
            return frame
        return cv2.undistort(frame, self.camera_matrix, self.distortion)

    def to_dict(self) -> dict[str, Any]:
        """Plain data (the calibration file)."""
        return {"homography": self.homography.tolist(), "error_cells": self.error_cells,
                "image_size": list(self.image_size),
                "reference": {str(k): list(v) for k, v in self.reference.items()},
                "camera_matrix": None if self.camera_matrix is None else self.camera_matrix.tolist(),
                "distortion": None if self.distortion is None else self.distortion.tolist()}

    def save(self, path: str | Path) -> None:
        """Write the calibration file (JSON)."""
        Path(path).write_text(json.dumps(self.to_dict(), indent=1))


def load_calibration(path: str | Path) -> Calibration:
    """Read a calibration file written by ``robo-comp camera calibrate``."""
    p = Path(path)
    try:
        d = json.loads(p.read_text())
        h = np.array(d["homography"], dtype=np.float64)
        if h.shape != (3, 3):
            raise ValueError("homography is not 3x3")
        return Calibration(h, float(d["error_cells"]), tuple(d["image_size"]),
                           {int(k): (float(v[0]), float(v[1])) for k, v in d["reference"].items()},
                           None if d.get("camera_matrix") is None else np.array(d["camera_matrix"]),
                           None if d.get("distortion") is None else np.array(d["distortion"]))
    except OSError as e:
        raise FieldError(f"cannot read the calibration {p}: {e.strerror}") from None
    except (ValueError, KeyError, TypeError) as e:
        raise FieldError(f"{p} is not a camera calibration ({e}); write one with robo-comp camera calibrate") from None


def calibrate(found: dict[int, np.ndarray], floor: dict[int, tuple[float, float]],
              image_size: tuple[int, int]) -> Calibration:
    """The homography from the floor markers seen in one frame (``found``: id → corners)."""
    seen = sorted(m for m in found if m in floor)
    if len(seen) < 4:
        raise FieldError(f"calibration needs 4 floor markers in view or more; this frame shows {len(seen)} "
                         f"({', '.join(map(str, seen)) or 'none'}) of the {len(floor)} in the marker file")
    src = np.array([found[m].mean(axis=0) for m in seen], dtype=np.float64)
    dst = np.array([floor[m] for m in seen], dtype=np.float64)
    h, _ = cv2.findHomography(src, dst, cv2.RANSAC if len(seen) > 4 else 0, 0.5)
    if h is None:
        raise FieldError("the floor markers in view are in a line or on top of each other: spread them "
                         "out (one near each corner of the camera's view)")
    err = float(np.sqrt(np.mean(np.sum((to_floor(h, src) - dst) ** 2, axis=1))))
    return Calibration(h, err, image_size, {m: (float(src[i, 0]), float(src[i, 1])) for i, m in enumerate(seen)})


def drift(cal: Calibration, found: dict[int, np.ndarray], floor: dict[int, tuple[float, float]]) -> float | None:
    """How far (cells, the largest) the floor markers in view now lie from their cells under
    ``cal``: above :data:`MOVED_CELLS` the camera has moved. None when none is in view."""
    seen = [m for m in found if m in floor]
    if not seen:
        return None
    now = to_floor(cal.homography, np.array([found[m].mean(axis=0) for m in seen]))
    want = np.array([floor[m] for m in seen])
    return float(np.max(np.linalg.norm(now - want, axis=1)))


def calibrate_intrinsics(images: list[np.ndarray], board: tuple[int, int] = (9, 6)) -> tuple[np.ndarray, np.ndarray, float]:
    """Camera matrix, distortion and RMS reprojection error (pixels) from views of a checkerboard
    with ``board`` inner corners (OpenCV's ``calibrateCamera``, Zhang's method)."""
    obj = np.zeros((board[0] * board[1], 3), np.float32)
    obj[:, :2] = np.mgrid[0:board[0], 0:board[1]].T.reshape(-1, 2)
    objs, imgs = [], []
    size = None
    for im in images:
        gray = im if im.ndim == 2 else cv2.cvtColor(im, cv2.COLOR_BGR2GRAY)
        size = gray.shape[::-1]
        ok, corners = cv2.findChessboardCorners(gray, board)
        if ok:
            corners = cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1),
                                       (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.01))
            objs.append(obj)
            imgs.append(corners)
    if len(objs) < 3 or size is None:
        raise FieldError(f"the checkerboard ({board[0]}x{board[1]} inner corners) was found in {len(objs)} "
                         "images; give 3 or more views of it from different angles")
    rms, k, dist, _, _ = cv2.calibrateCamera(objs, imgs, size, None, None)
    return k, dist, float(rms)

"""The markers: OpenCV's ArUco 4×4 dictionary (250 ids), images of them and a printable sheet."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from robo_comp.errors import FieldError

#: The dictionary every camera and every sheet uses: 4×4 bits, 250 ids (0..249).
DICTIONARY = cv2.aruco.DICT_4X4_250
MAX_ID = 249


def dictionary() -> cv2.aruco.Dictionary:
    """The ArUco dictionary of :data:`DICTIONARY`."""
    return cv2.aruco.getPredefinedDictionary(DICTIONARY)


def check_id(marker: object) -> int:
    """A marker id as an int in 0..:data:`MAX_ID`, or :class:`FieldError` saying what is wrong."""
    if type(marker) is not int or not 0 <= marker <= MAX_ID:
        raise FieldError(f"marker ids are whole numbers 0..{MAX_ID} (ArUco 4x4 dictionary), not {marker!r}")
    return marker


def marker_image(marker: int, pixels: int = 120) -> np.ndarray:
    """Marker ``marker`` as a square grayscale image ``pixels`` wide (black border included)."""
    return cv2.aruco.generateImageMarker(dictionary(), check_id(marker), pixels)


def write_sheet(path: str | Path, markers: list[int], *, cm: float = 10.0, dpi: int = 150) -> Path:
    """A printable PNG sheet (A4 at ``dpi``) of ``markers``, each ``cm`` wide with a white margin
    and its id written under it. Print at 100 % scale: the cameras assume the printed size."""
    px_per_cm = dpi / 2.54
    side = int(round(cm * px_per_cm))
    margin = max(20, side // 4)
    cols = max(1, int((21.0 * px_per_cm - margin) // (side + margin)))
    rows = (len(markers) + cols - 1) // cols
    sheet = np.full((margin + rows * (side + 2 * margin), margin + cols * (side + margin)), 255, np.uint8)
    for i, m in enumerate(markers):
        r, c = divmod(i, cols)
        y0, x0 = margin + r * (side + 2 * margin), margin + c * (side + margin)
        sheet[y0:y0 + side, x0:x0 + side] = marker_image(m, side)
        cv2.putText(sheet, f"id {m}  ({cm:g} cm)", (x0, y0 + side + margin // 2 + 8), cv2.FONT_HERSHEY_SIMPLEX,
                    max(0.4, side / 300), 0, 1, cv2.LINE_AA)
    out = Path(path)
    if not cv2.imwrite(str(out), sheet):
        raise FieldError(f"cannot write the marker sheet to {out}")
    return out

"""Short videos of a robot's camera: frames written as WebM (VP8) with OpenCV's ``VideoWriter``,
read back with ``VideoCapture``.

``examineArea`` films its turn on the spot (the thesis's video of an examined area, §4.4.5, which
never worked there): the task runtime takes a camera frame every ``1 / FPS`` seconds of the turn
and the robot's host writes them as one WebM file, which the core keeps like a picture. A
browser plays WebM VP8 as it is (the web page's ``<video>``); the wall reads the frames back.
"""
from __future__ import annotations

import os
import tempfile
from typing import Any

import numpy as np

from robo_comp.errors import FieldError

#: Frames per second of a robot's video.
FPS = 8
#: The most frames one video holds (20 seconds at :data:`FPS`).
MAX_FRAMES = 160
#: The first bytes of every WebM (Matroska) file.
WEBM_MAGIC = b"\x1a\x45\xdf\xa3"


def encode_webm(frames: list[Any], fps: float = FPS) -> bytes:
    """``frames`` (RGB ``uint8`` arrays of one size, as the arena's camera gives them) as a WebM
    (VP8) video; ``FieldError`` if there are none or OpenCV cannot write WebM here."""
    import cv2

    if not frames:
        raise FieldError("a video needs at least one frame")
    h, w = frames[0].shape[:2]
    fd, path = tempfile.mkstemp(suffix=".webm")
    os.close(fd)
    try:
        # OpenCV says on stderr that the tag 'VP80' is not WebM's, then writes VP8 with WebM's own tag
        fourcc = cv2.VideoWriter.fourcc(*"VP80")
        writer = cv2.VideoWriter(path, fourcc, float(fps), (int(w), int(h)))
        if not writer.isOpened():
            raise FieldError("OpenCV cannot write WebM (VP8) video on this machine")
        try:
            for f in frames:
                writer.write(cv2.cvtColor(np.ascontiguousarray(f, dtype=np.uint8), cv2.COLOR_RGB2BGR))
        finally:
            writer.release()
        with open(path, "rb") as fh:
            return fh.read()
    finally:
        os.unlink(path)


def decode_webm(data: bytes, limit: int = MAX_FRAMES) -> list[Any]:
    """The frames of a WebM video (RGB ``uint8`` arrays), at most ``limit``."""
    import cv2

    if not data.startswith(WEBM_MAGIC):
        raise FieldError("not a WebM video")
    fd, path = tempfile.mkstemp(suffix=".webm")
    try:
        os.write(fd, data)
        os.close(fd)
        cap = cv2.VideoCapture(path)
        frames: list[Any] = []
        try:
            while len(frames) < limit:
                ok, f = cap.read()
                if not ok:
                    break
                frames.append(cv2.cvtColor(f, cv2.COLOR_BGR2RGB))
        finally:
            cap.release()
        return frames
    finally:
        os.unlink(path)


__all__ = ["FPS", "MAX_FRAMES", "WEBM_MAGIC", "decode_webm", "encode_webm"]

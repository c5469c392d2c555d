"""The positioning source: camera frames in, robot fixes out on a ZeroMQ PUB socket.

``robo-comp camera run`` reads frames from one or more cameras (a device number, a video file,
a folder of images, or ``synthetic:URL`` — frames drawn from a simulating host's true poses),
finds the markers, maps them onto the floor with each camera's calibration, fuses what several
cameras saw into one pose per bound robot and publishes, for every frame, one message::

    topic b"fixes": {"t": unix time, "seq": n, "fixes": [{"robot": "red-1", "x": 3.02, "y": 7.48,
                     "heading": 91.2, "sigma": 0.05, "cameras": [0]}, ...]}

and, when a camera's floor markers have drifted from their calibrated cells (the camera moved)::

    topic b"camera": {"camera": 0, "drift": 0.8, "moved": true, "message": "..."}

Robot hosts subscribe (``robo-comp robots --positioning camera:URL``) and correct their robots'
dead reckoning with the fixes for their own robots only.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import zmq

from robo_comp import protocol as P
from robo_comp.errors import FieldError
from robo_comp.protocol.curve import load_secret, open_server
from robo_comp.world.overhead.binding import Bindings
from robo_comp.world.overhead.calibrate import MOVED_CELLS, Calibration, calibrate, drift
from robo_comp.world.overhead.detect import Detector, poses
from robo_comp.world.overhead.fuse import FusedPose, Sighting, fuse
from robo_comp.world.overhead.synth import SyntheticCamera, cameras_for

log = logging.getLogger("robo_comp.camera")

#: A robot marker whose side on the floor is outside this range (cells) is a misdetection.
SIDE_RANGE = (0.2, 3.0)
#: σ (cells) a sighting gets at least, whatever its camera's calibration error.
SIGHTING_SIGMA = 0.05


@dataclass
class Located:
    """One frame set's result: a fused pose per robot, and each camera's floor-marker drift."""

    fixes: dict[str, FusedPose]
    drifts: list[float | None]


class Locator:
    """Frames of calibrated cameras → one pose per bound robot."""

    def __init__(self, bindings: Bindings, calibrations: list[Calibration]) -> None:
        self.bindings = bindings
        self.calibrations = calibrations
        self.detector = Detector()

    def locate(self, frames: list[np.ndarray | None]) -> Located:
        """Detect, map and fuse (a camera whose frame is None this time is skipped)."""
        seen: dict[str, list[Sighting]] = {}
        drifts: list[float | None] = []
        for i, (frame, cal) in enumerate(zip(frames, self.calibrations)):
            if frame is None:
                drifts.append(None)
                continue
            found = self.detector.detect(cal.undistort(frame))
            drifts.append(drift(cal, found, self.bindings.floor))
            sigma = max(cal.error_cells, SIGHTING_SIGMA)
            robots = {m: c for m, c in found.items() if m in self.bindings.robots}
            for m, p in poses(robots, cal.homography).items():
                if SIDE_RANGE[0] <= p.side <= SIDE_RANGE[1]:
                    seen.setdefault(self.bindings.robots[m], []).append(Sighting(p.x, p.y, p.heading, sigma, i))
        return Located({rid: fuse(s) for rid, s in seen.items()}, drifts)


def fixes_message(located: Located, seq: int, t: float) -> dict[str, Any]:
    """The body of one ``fixes`` message."""
    return {"t": t, "seq": seq, "fixes": [
        {"robot": rid, "x": round(p.x, 4), "y": round(p.y, 4), "heading": round(p.heading, 2),
         "sigma": round(p.sigma, 4), "cameras": list(p.cameras)} for rid, p in sorted(located.fixes.items())]}


# ---------------------------------------------------------------------- frame sources
def open_frames(spec: str) -> Iterator[np.ndarray]:
    """Grayscale frames from a camera device (``0``), a video file, or a folder of images (in name
    order). :class:`FieldError` when the source cannot be opened."""
    p = Path(spec)
    if p.is_dir():
        files = sorted(f for f in p.iterdir() if f.suffix.lower() in (".png", ".jpg", ".jpeg", ".bmp"))
        if not files:
            raise FieldError(f"{p}: no .png/.jpg images in this folder")
        return (im for im in (cv2.imread(str(f), cv2.IMREAD_GRAYSCALE) for f in files) if im is not None)
    cap = cv2.VideoCapture(int(spec) if spec.isdigit() else spec)
    if not cap.isOpened():
        raise FieldError(f"cannot open the camera or video {spec!r} (a device number, a video file or a folder)")

    def frames() -> Iterator[np.ndarray]:
        try:
            while True:
                ok, frame = cap.read()
                if not ok:
                    return
                yield frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        finally:
            cap.release()
    return frames()


class TruthFeed:
    """The true poses simulating robot hosts publish (``robo-comp robots --truth-pub URL``, one
    URL per host, comma-separated): what the synthetic cameras draw. Each robot's newest pose wins."""

    def __init__(self, ctx: zmq.Context, urls: str) -> None:
        self.sock = ctx.socket(zmq.SUB)
        self.sock.setsockopt(zmq.LINGER, 0)
        self.sock.setsockopt(zmq.RCVHWM, 100)
        self.sock.setsockopt(zmq.SUBSCRIBE, b"truth")
        for url in urls.split(","):
            self.sock.connect(url.strip())
        self.robots: dict[str, tuple[float, float, float]] = {}
        self.walls: np.ndarray | None = None

    def poll(self, timeout_ms: int = 0) -> dict[str, tuple[float, float, float]] | None:
        """Every robot's newest true pose (waiting up to ``timeout_ms`` for the first message);
        None before any came."""
        if self.sock.poll(timeout_ms if self.walls is None else 0):
            while True:
                try:
                    _, body = self.sock.recv_multipart(zmq.NOBLOCK)
                except zmq.Again:
                    break
                msg = P.unpack(body)
                if self.walls is None:
                    h, w = msg["h"], msg["w"]
                    self.walls = np.unpackbits(np.frombuffer(msg["walls"], np.uint8), count=h * w).reshape(h, w).astype(bool)
                for rid, x, y, hd in msg["robots"]:
                    self.robots[rid] = (x, y, hd)
        return self.robots if self.walls is not None else None


def synthetic_rig(bindings: Bindings, walls: np.ndarray, cameras: int) -> tuple[list[SyntheticCamera], list[Calibration]]:
    """Synthetic cameras over the arena and their calibrations, made the way an organiser makes
    them: a frame of each camera with only the floor markers, through :func:`calibrate`."""
    h, w = walls.shape
    cams = cameras_for(w, h, cameras)
    det = Detector()
    cals = []
    for i, cam in enumerate(cams):
        cal = calibrate(det.detect(cam.render(walls, [], bindings.floor)), bindings.floor, cam.size)
        log.info("synthetic camera %d calibrated: %.4f cells RMS", i, cal.error_cells)
        cals.append(cal)
    return cams, cals


def run(bindings: Bindings, pub_url: str, *, sources: list[str] | None = None,
        calibrations: list[Calibration] | None = None, truth_url: str | None = None, cameras: int = 1,
        fps: float = 10.0, duration: float | None = None, key: str | Path | None = None) -> int:
    """Serve fixes on ``pub_url`` until ``duration`` (or forever): from ``sources`` with their
    ``calibrations``, or from synthetic cameras drawing ``truth_url``'s arena. Returns frames done.

    ``key`` is the organiser's secret certificate (``STATE/keys/organiser.key_secret``): the PUB
    socket is then a CurveZMQ server with that key, and hosts that pin its public half
    (``robots --camera-key``) know the fixes are the organiser's camera's. Without it the fixes
    go out in the clear and hosts refuse them."""
    ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context.instance()
    pub = ctx.socket(zmq.PUB)
    pub.setsockopt(zmq.LINGER, 0)
    pub.setsockopt(zmq.SNDHWM, 100)
    if key is not None:
        open_server(pub, *load_secret(key))  # any host may listen; only the camera speaks with this key
    pub.bind(pub_url)
    robot_marker = {r: m for m, r in bindings.robots.items()}
    truth: TruthFeed | None = None
    rig: list[SyntheticCamera] = []
    streams: list[Iterator[np.ndarray]] = []
    if truth_url is not None:
        truth = TruthFeed(ctx, truth_url)
        if truth.poll(30_000) is None or truth.walls is None:
            raise FieldError(f"no true poses from {truth_url} within 30 s: start the robot host with --truth-pub")
        rig, calibrations = synthetic_rig(bindings, truth.walls, cameras)
    else:
        if not sources or not calibrations or len(sources) != len(calibrations):
            raise FieldError("give one --calibration per --source (robo-comp camera calibrate writes them)")
        streams = [open_frames(s) for s in sources]
    locator = Locator(bindings, calibrations)
    seq = 0
    t_end = None if duration is None else time.monotonic() + duration
    next_frame = time.monotonic()
    warned = 0.0
    try:
        while t_end is None or time.monotonic() < t_end:
            if truth is not None:
                now = time.monotonic()
                if now < next_frame:
                    time.sleep(next_frame - now)
                next_frame = max(next_frame + 1.0 / fps, time.monotonic())
                state = truth.poll()
                assert state is not None and truth.walls is not None
                robots = [(robot_marker[r], x, y, hd) for r, (x, y, hd) in state.items() if r in robot_marker]
                frames: list[np.ndarray | None] = [cam.render(truth.walls, robots, bindings.floor) for cam in rig]
            else:
                frames = [next(s, None) for s in streams]
                if all(f is None for f in frames):
                    break
            located = locator.locate(frames)
            pub.send_multipart([b"fixes", P.pack(fixes_message(located, seq, time.time()))])
            seq += 1
            if time.monotonic() - warned > 1.0:
                for i, d in enumerate(located.drifts):
                    if d is not None and d > MOVED_CELLS:
                        msg = (f"camera {i}: its floor markers are {d:.2f} cells from where the calibration puts "
                               "them; it has moved: calibrate it again (robo-comp camera calibrate)")
                        log.warning("%s", msg)
                        pub.send_multipart([b"camera", P.pack({"camera": i, "drift": round(d, 3), "moved": True,
                                                               "message": msg})])
                        warned = time.monotonic()
    finally:
        pub.close(0)
    return seq

"""``robo-comp camera``: print markers, calibrate a camera, run the positioning source."""
from __future__ import annotations

import argparse
from pathlib import Path

from robo_comp.errors import FieldError


def _ids(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        try:
            out += list(range(int(a), int(b or a) + 1))
        except ValueError:
            raise argparse.ArgumentTypeError(f"marker ids like 0-19,40 expected, not {text!r}") from None
    return out


def _markers(args: argparse.Namespace) -> int:
    from robo_comp.world.overhead.markers import write_sheet

    out = write_sheet(args.out, args.ids, cm=args.cm)
    print(f"{len(args.ids)} markers, {args.cm:g} cm each, in {out}: print at 100 % scale")
    return 0


def _calibrate(args: argparse.Namespace) -> int:
    import cv2

    from robo_comp.world.overhead.binding import load_bindings
    from robo_comp.world.overhead.calibrate import calibrate, calibrate_intrinsics
    from robo_comp.world.overhead.detect import Detector

    bindings = load_bindings(args.markers)
    frame = cv2.imread(args.image, cv2.IMREAD_GRAYSCALE)
    if frame is None:
        raise FieldError(f"cannot read the image {args.image}")
    k = dist = None
    if args.checkerboard:
        views = [im for f in sorted(Path(args.checkerboard).iterdir())
                 if (im := cv2.imread(str(f), cv2.IMREAD_GRAYSCALE)) is not None]
        k, dist, rms = calibrate_intrinsics(views, tuple(args.board))
        print(f"intrinsics from {len(views)} checkerboard views: {rms:.3f} pixels RMS reprojection error")
        frame = cv2.undistort(frame, k, dist)
    cal = calibrate(Detector().detect(frame), bindings.floor, (frame.shape[1], frame.shape[0]))
    cal.camera_matrix, cal.distortion = k, dist
    cal.save(args.out)
    print(f"{len(cal.reference)} floor markers in view; reprojection error {cal.error_cells:.4f} cells RMS"
          + (" (exactly 4 markers: the fit is exact, add a fifth to check it)" if len(cal.reference) == 4 else "")
          + f"; written to {args.out}")
    return 0


def _run(args: argparse.Namespace) -> int:
    from robo_comp.world.overhead.binding import load_bindings
    from robo_comp.world.overhead.calibrate import load_calibration
    from robo_comp.world.overhead.source import run

    bindings = load_bindings(args.markers)
    cals = [load_calibration(c) for c in args.calibration or []]
    n = run(bindings, args.pub, sources=args.source, calibrations=cals, truth_url=args.synthetic,
            cameras=args.cameras, fps=args.fps, duration=args.duration or None, key=args.key)
    print(f"{n} frames")
    return 0


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``robo-comp camera`` and its subcommands."""
    cam = sub.add_parser("camera", help="the overhead-camera positioning system (ArUco markers)",
                         description="Overhead cameras see a marker on every robot and feed robot hosts "
                                     "real positions (docs/positioning.md).")
    cs = cam.add_subparsers(dest="camera_command", required=True)
    m = cs.add_parser("markers", help="write a printable sheet of markers")
    m.add_argument("out", help="PNG file to write")
    m.add_argument("--ids", type=_ids, default=_ids("0-11"), help="marker ids, e.g. 0-19,200-203 (default 0-11)")
    m.add_argument("--cm", type=float, default=18.0, help="printed side of each marker in cm (default 18)")
    m.set_defaults(func=_markers)
    c = cs.add_parser("calibrate", help="calibrate a camera from a frame showing 4 or more floor markers")
    c.add_argument("image", help="a frame of the camera (PNG/JPG) with the floor markers in view")
    c.add_argument("out", help="calibration file to write (JSON)")
    c.add_argument("--markers", required=True, help="the organiser's marker file (TOML: [robots], [floor])")
    c.add_argument("--checkerboard", help="a folder of checkerboard views: measure the lens's intrinsics too")
    c.add_argument("--board", type=int, nargs=2, default=(9, 6), metavar=("COLS", "ROWS"),
                   help="inner corners of the checkerboard (default 9 6)")
    c.set_defaults(func=_calibrate)
    r = cs.add_parser("run", help="serve robot fixes from camera frames on a ZeroMQ PUB socket")
    r.add_argument("--markers", required=True, help="the organiser's marker file (TOML: [robots], [floor])")
    r.add_argument("--pub", default="tcp://127.0.0.1:5570", help="where hosts subscribe (default tcp://127.0.0.1:5570)")
    r.add_argument("--source", action="append", help="a camera: device number, video file or image folder (repeat for several)")
    r.add_argument("--calibration", action="append", help="its calibration file (one per --source, in order)")
    r.add_argument("--synthetic", metavar="TRUTH_URL[,TRUTH_URL...]",
                   help="no camera: draw synthetic frames of simulating hosts' arena (robots --truth-pub URL)")
    r.add_argument("--cameras", type=int, default=1, help="synthetic cameras side by side (default 1)")
    r.add_argument("--fps", type=float, default=10.0, help="synthetic frames per second (default 10)")
    r.add_argument("--duration", type=float, default=0.0, help="stop after S seconds (0 = run until stopped)")
    r.add_argument("--key", metavar="SECRET_CERT",
                   help="the organiser's secret certificate (STATE/keys/organiser.key_secret, made by robo-comp "
                        "keys): fixes go out over CurveZMQ under this key, and hosts that pin its public half "
                        "(robots --camera-key) take them; without it hosts refuse the fixes")
    r.set_defaults(func=_run)

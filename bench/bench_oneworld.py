"""A simulated robot's range sensor sees a camera-tracked robot: how long after the robot is there.

A core; a blue robot host (one simulated robot, positions from the camera, ``--truth-pub``); a
synthetic overhead camera process (``robo-comp camera run --synthetic``, under the organiser's key)
drawing the blue robot and a robot ``red-1`` that no host of this bench runs (a camera-tracked
robot: its true pose is published by the bench, as the simulated ROS 2 robot publishes its own). The
blue robot stands facing east along a free row; ``red-1`` is put alternately three cells ahead of it
and away out of its line. Measured from the moment the bench publishes the new true pose:

* to the camera's first fix of ``red-1`` there (the bench subscribes to the fixes as a host does):
  the camera's share (frame, detection, fix);
* to the blue robot's reported front reading showing it (its team's monitor, polled every 20 ms):
  camera + the blue host's arena + its next report with readings.

Printed beside the host's sensing period (``robots --sensor-hz``, 2 by default: 0.5 s) and the
load. ``--baseline REV`` runs the blue host of git revision REV too, interleaved in the same run
(the core and camera are this tree's), for a before/after.

    .venv/bin/python bench/bench_oneworld.py --moves 20 [--baseline REV] [--reps 1]
"""
from __future__ import annotations

import argparse
import math
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import zmq

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_core import _export  # noqa: E402
from robo_comp import protocol as P  # noqa: E402
from robo_comp.launch import start_core, stop_all  # noqa: E402
from robo_comp.protocol import unpack_walls  # noqa: E402
from robo_comp.protocol.curve import ClientKeys, create_keys, load_public, secure_client  # noqa: E402
from robo_comp.testing import Match, wait_for, wait_robots  # noqa: E402
from robo_comp.world.overhead.binding import Bindings  # noqa: E402
from robo_comp.world.overhead.synth import floor_markers  # noqa: E402

#: The host's sensing period unless --sensor-hz is given (RobotHost's default).
SENSING_PERIOD = 0.5


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _fixes_sub(ctx: zmq.Context, url: str, camera_key: Path) -> zmq.Socket:
    """The camera's fixes, as a host takes them (CurveZMQ, the camera's key pinned)."""
    public, secret = zmq.curve_keypair()
    sub = ctx.socket(zmq.SUB)
    sub.setsockopt(zmq.LINGER, 0)
    secure_client(sub, ClientKeys(public, secret, load_public(camera_key)))
    sub.setsockopt(zmq.SUBSCRIBE, b"fixes")
    sub.connect(url)
    return sub


def _red_fix(sub: zmq.Socket) -> tuple[float, float] | None:
    """The newest fix of red-1 among the fixes waiting on ``sub`` (None: none)."""
    got = None
    while True:
        try:
            _, body = sub.recv_multipart(zmq.NOBLOCK)
        except zmq.Again:
            return got
        for f in P.unpack(body).get("fixes") or []:
            if f.get("robot") == "red-1":
                got = (float(f["x"]), float(f["y"]))


def measure(moves: int, tree: Path | None) -> tuple[list[float], list[float]]:
    """One setup (core, blue host of ``tree`` or this one, camera); ``moves`` times red-1 put ahead.
    Returns the latencies (s) truth -> camera fix and truth -> reported front reading."""
    state = Path(tempfile.mkdtemp(prefix="bench_oneworld_"))
    fixes, truth_blue, truth_red = (f"tcp://127.0.0.1:{_port()}" for _ in range(3))
    procs = [start_core(state, "--teams", "red,blue", "--heartbeat", "1")]
    create_keys(state, ["red", "blue"])  # the camera speaks under the organiser's key; the host pins it
    match = Match(state, None, procs[0])
    ctx = zmq.Context.instance()
    pub = ctx.socket(zmq.PUB)
    pub.setsockopt(zmq.LINGER, 0)
    pub.bind(truth_red)
    sub = _fixes_sub(ctx, fixes, state / "keys" / "organiser.key")
    try:
        env = dict(os.environ, PYTHONPATH=str(tree)) if tree is not None else None
        with open(state / "robots-blue.log", "ab") as log:
            procs.append(subprocess.Popen(
                [sys.executable, "-m", "robo_comp.cli", "robots", "--core", str(state), "--token-file",
                 str(match.host_token_file("blue")), "--count", "1", "--seed", "1", "--positioning",
                 f"camera:{fixes}", "--truth-pub", truth_blue], env=env, stdout=log, stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL, cwd=tree))  # (python -m puts its folder before PYTHONPATH)
        blue = match.client("blue")
        row = wait_robots(blue, 1, timeout=180)[0]  # a tree of its own compiles its kernels first
        walls = unpack_walls(blue.arena())
        h, w = walls.shape
        packed = np.packbits(walls, axis=None).tobytes()
        # a free row: blue at (cx - 3, cy) facing east, red-1 in (cx, cy) or out of line at (cx, cy - 1)
        cx, cy = next((x, y) for y in range(1, h - 1) for x in range(5, w - 2)
                      if not walls[y - 1:y + 2, x - 5:x + 2].any())
        away = (cx, cy - 1)
        here = (cx, cy)

        def truth(cell: tuple[int, int]) -> None:
            pub.send_multipart([b"truth", P.pack({"w": w, "h": h, "walls": packed,
                                                  "robots": [["red-1", float(cell[0]), float(cell[1]), 180.0]]})])

        (state / "markers.toml").write_text(Bindings({10: "red-1", 11: "blue-1"}, floor_markers(w, h)).to_toml())
        truth(away)
        procs.append(subprocess.Popen([sys.executable, "-m", "robo_comp.cli", "camera", "run", "--markers",
                                       str(state / "markers.toml"), "--pub", fixes, "--key",
                                       str(state / "keys" / "organiser.key_secret"), "--synthetic",
                                       f"{truth_blue},{truth_red}", "--fps", "10"],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        for _ in range(4):  # again while it stopped short (the camera's frames lag on a loaded machine)
            tid = blue.give(row["tag"], "followPath", [[[cx - 4, cy], [cx - 3, cy]]])["task_id"]
            wait_for(lambda: (truth(away), any(t["task_id"] == tid for t in blue.monitor(row["tag"])["done"]))[1],
                     90, "the blue robot in place")
            t_end = time.monotonic() + 1.5
            while time.monotonic() < t_end:
                truth(away)
                time.sleep(0.05)
            m = blue.monitor(row["tag"])
            if math.hypot(m["x"] - (cx - 3), m["y"] - cy) < 0.3 and abs((m["heading"] + 180) % 360 - 180) < 8:
                break

        def front() -> float:
            return float((blue.monitor(row["tag"]).get("sensors") or {}).get("front") or math.inf)

        m = blue.monitor(row["tag"])
        print(f"  blue robot at ({m['x']:.2f}, {m['y']:.2f}) heading {m['heading']:.0f}, red-1 at {here} or {away}; "
              f"front now {front():.1f} cm", flush=True)
        seen: list[float] = []
        fixed: list[float] = []
        for i in range(moves):
            # away: wait until the reading is far, then put red-1 ahead and time the fix and the reading
            t_end = time.monotonic() + 10
            while front() < 100:
                truth(away)
                time.sleep(0.02)
                if time.monotonic() > t_end:
                    raise SystemExit(f"the blue robot's front reading stays {front():.1f} cm with red-1 away")
            time.sleep(0.2 + 0.3 * (i % 4) / 4)  # not in step with the host's report ticks
            _red_fix(sub)  # the fixes so far are of red-1 away
            t0 = time.monotonic()
            t_fix = None
            while True:
                truth(here)  # a simulating host publishes its truth every tick
                fix = _red_fix(sub)
                if t_fix is None and fix is not None and math.hypot(fix[0] - here[0], fix[1] - here[1]) < 0.5:
                    t_fix = time.monotonic()
                    fixed.append(t_fix - t0)
                if front() < 75:
                    seen.append(time.monotonic() - t0)
                    break
                if time.monotonic() - t0 > 10:
                    print(f"  move {i}: not seen within 10 s", file=sys.stderr)
                    break
                time.sleep(0.02)
            truth(away)
        return fixed, seen
    finally:
        pub.close(0)
        sub.close(0)
        for c in match.clients:
            c.close()
        stop_all(procs)


def _summary(name: str, fixed: list[float], seen: list[float], moves: int) -> None:
    a, f = np.asarray(seen) * 1000, np.asarray(fixed) * 1000
    print(f"{name}: red-1 put in front of the blue robot {moves} times, seen {len(seen)} times")
    if len(f):
        print(f"  truth -> camera fix of red-1:             p50 {np.percentile(f, 50):5.0f} ms, "
              f"p99 {np.percentile(f, 99):5.0f} ms, max {f.max():5.0f} ms")
    if len(a):
        print(f"  truth -> reported front reading sees it:  p50 {np.percentile(a, 50):5.0f} ms, "
              f"p99 {np.percentile(a, 99):5.0f} ms, max {a.max():5.0f} ms  "
              f"(sensing period {SENSING_PERIOD * 1000:.0f} ms)")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--moves", type=int, default=20, help="times red-1 is put in front of the blue robot")
    ap.add_argument("--baseline", default="", metavar="REV",
                    help="also measure the blue host of this git revision, interleaved (before/after)")
    ap.add_argument("--reps", type=int, default=1, help="setups per tree (alternating with --baseline)")
    args = ap.parse_args()
    print(f"load: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f} "
          f"({os.cpu_count()} cores)", flush=True)
    runs: dict[str, tuple[list[float], list[float]]] = {"after": ([], []), "before": ([], [])}
    with tempfile.TemporaryDirectory() as tmp:
        old = _export(args.baseline, Path(tmp)) if args.baseline else None
        for rep in range(args.reps):
            order: list[tuple[str, Path | None]] = [("after", None)]
            if old is not None:
                order = order + [("before", old)] if rep % 2 == 0 else [("before", old)] + order
            for name, tree in order:
                print(f"{name} ({args.baseline if tree else 'this tree'}), setup {rep + 1}:", flush=True)
                fixed, seen = measure(args.moves, tree)
                runs[name][0].extend(fixed)
                runs[name][1].extend(seen)
    for name, (fixed, seen) in runs.items():
        if seen or fixed:
            _summary(name if old is not None else "this tree", fixed, seen, args.moves * args.reps)
    print(f"load: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

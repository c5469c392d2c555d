"""A simulated robot's range sensor sees a camera-tracked robot: how long after the robot is there.

A core; a blue robot host (one simulated robot, positions from the camera, ``--truth-pub``); a
synthetic overhead camera process (``robo-comp camera run --synthetic``) drawing the blue robot
and a robot ``red-1`` that no host of this bench runs (a camera-tracked robot: its true pose is
published by the bench, as the simulated ROS 2 robot publishes its own). The blue robot stands
facing east along a free row; ``red-1`` is put alternately three cells ahead of it and away out
of its line. Measured: from the moment the bench publishes the new true pose to the moment the
blue robot's reported front reading (its team's monitor, polled every 20 ms) shows it:
camera frame + detection + fix + the blue host's arena + the next sensor report. Printed beside
the host's sensing period (sensors read every 0.5 s, a standing robot reported once a second).

    .venv/bin/python bench/bench_oneworld.py --moves 20
"""
from __future__ import annotations

import argparse
import math
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import zmq

from robo_comp import protocol as P
from robo_comp.launch import start_core, start_robots, stop_all
from robo_comp.protocol import unpack_walls
from robo_comp.testing import Match, wait_for, wait_robots
from robo_comp.world.overhead.binding import Bindings
from robo_comp.world.overhead.synth import floor_markers


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--moves", type=int, default=20, help="times red-1 is put in front of the blue robot")
    args = ap.parse_args()
    state = Path(tempfile.mkdtemp(prefix="bench_oneworld_"))
    fixes, truth_blue, truth_red = (f"tcp://127.0.0.1:{_port()}" for _ in range(3))
    procs = [start_core(state, "--teams", "red,blue", "--heartbeat", "1")]
    match = Match(state, None, procs[0])
    pub = zmq.Context.instance().socket(zmq.PUB)
    pub.setsockopt(zmq.LINGER, 0)
    pub.bind(truth_red)
    try:
        procs.append(start_robots(state, "blue", 1, "--seed", "1", "--positioning", f"camera:{fixes}",
                                  "--truth-pub", truth_blue))
        blue = match.client("blue")
        row = wait_robots(blue, 1)[0]
        walls = unpack_walls(blue.arena())
        h, w = walls.shape
        packed = np.packbits(walls, axis=None).tobytes()
        # a free row: blue at (cx - 3, cy) facing east, red-1 in (cx, cy) or out of line at (cx, cy - 1)... away
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
                                       str(state / "markers.toml"), "--pub", fixes, "--synthetic",
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
        print(f"blue robot at ({m['x']:.2f}, {m['y']:.2f}) heading {m['heading']:.0f}, red-1 at {here} or {away}; "
              f"front now {front():.1f} cm", flush=True)
        lat: list[float] = []
        for i in range(args.moves):
            # away: wait until the reading is far, then put red-1 ahead and time the reading's change
            t_end = time.monotonic() + 10
            while front() < 100:
                truth(away)
                time.sleep(0.02)
                if time.monotonic() > t_end:
                    raise SystemExit(f"the blue robot's front reading stays {front():.1f} cm with red-1 away")
            t0 = time.monotonic()
            while True:
                truth(here)  # a simulating host publishes its truth every tick
                if front() < 75:
                    lat.append(time.monotonic() - t0)
                    break
                if time.monotonic() - t0 > 10:
                    print(f"move {i}: not seen within 10 s", file=sys.stderr)
                    break
                time.sleep(0.02)
            truth(away)
        a = np.asarray(lat) * 1000
        print(f"red-1 put in front of the blue robot {args.moves} times, seen {len(lat)} times")
        print(f"truth -> reported front reading: p50 {np.percentile(a, 50):.0f} ms, p99 {np.percentile(a, 99):.0f} ms, "
              f"max {a.max():.0f} ms; the host's sensor interval 500 ms, a standing robot reported every 1000 ms")
    finally:
        pub.close(0)
        for c in match.clients:
            c.close()
        stop_all(procs)
    return 0


if __name__ == "__main__":
    sys.exit(main())

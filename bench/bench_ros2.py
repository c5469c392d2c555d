"""Stop through the ROS 2 driver beside the simulated driver, in one run.

For each driver a core, a ``robo-comp robots`` host process with one robot and (for ``ros2``)
a simulated ROS 2 robot process (``robo_comp.robots.ros2.simrobot``) on a DDS bus kept on
loopback (``CYCLONEDDS_URI`` naming ``lo``, no multicast, peer 127.0.0.1, a domain id of its
own). The robot is sent back and forth between two far cells; while it drives, a team client
sends ``stop`` and the bench measures

* request → reply (the host halted the robot and answered, through the core), both drivers;
* request → the zero ``Twist`` arriving on ``/tb1/cmd_vel`` (a reader in this process, as the
  robot reads it), ``ros2`` only: what "stopped at once" means for a ROS 2 robot.

    .venv/bin/python bench/bench_ros2.py --stops 60
"""
from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from robo_comp.launch import start_core, start_robots, stop_all
from robo_comp.testing import Match, wait_robots


def pct(xs: list[float], q: float) -> float:
    """The q-th percentile in ms."""
    return float(np.percentile(np.asarray(xs) * 1000.0, q))


def far_cells(walls: np.ndarray, start: tuple[int, int]) -> list[tuple[int, int]]:
    """Two free cells a few cells apart in a straight free line through ``start``."""
    h, w = walls.shape
    x, y = start
    for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        cells = [(x + k * dx, y + k * dy) for k in range(0, 5)]
        if all(0 <= cx < w and 0 <= cy < h and not walls[cy, cx] for cx, cy in cells):
            return [cells[-1], cells[0]]
    raise SystemExit("no straight free run of 4 cells next to the robot")


def run(driver: str, stops: int, domain: int) -> dict[str, list[float]]:
    """``stops`` stops of a driving robot through ``driver``; the latencies in seconds."""
    from robo_comp.protocol import unpack_walls

    state = Path(tempfile.mkdtemp(prefix=f"bench_ros2_{driver}_"))
    procs = [start_core(state, "--teams", "red,blue", "--heartbeat", "1")]
    match = Match(state, None, procs[0])
    extra: list[str] = ["--seed", "5"]
    if driver == "ros2":
        extra += ["--driver", "ros2", "--ros2-ns", "tb1", "--ros2-domain", str(domain), "--ros2-speed", "0.25"]
    procs.append(start_robots(state, "red", 1, *extra))
    watch = bus = None
    out: dict[str, list[float]] = {"reply": [], "zero": []}
    try:
        red = match.client("red")
        row = wait_robots(red, 1)[0]
        start = (round(row["x"]), round(row["y"]))
        if driver == "ros2":
            from robo_comp.robots.ros2.bus import Bus
            from robo_comp.robots.ros2.watch import CommandWatch, is_zero

            sim = subprocess.Popen([sys.executable, "-m", "robo_comp.robots.ros2.simrobot", "--ns", "tb1",
                                    "--domain", str(domain), "--x", str(start[0]), "--y", str(start[1])],
                                   stdout=subprocess.PIPE, text=True)
            procs.append(sim)  # type: ignore[arg-type]
            assert sim.stdout is not None and sim.stdout.readline().strip() == "ready"
            bus = Bus.shared(domain)
            watch = CommandWatch(bus, "tb1")
        goals = far_cells(unpack_walls(red.arena()), start)
        for _ in range(stops):
            mark = watch.mark() if watch is not None else 0
            m = red.monitor(row["tag"])  # to the goal farther away: a goTo to its own cell would not drive
            goal = max(goals, key=lambda c: (c[0] - m["x"]) ** 2 + (c[1] - m["y"]) ** 2)
            red.give(row["tag"], "goTo", list(goal))
            if watch is not None:
                watch.wait(lambda v, w: v != 0.0 or w != 0.0, 10, "a drive command", since=mark)
            time.sleep(0.15)  # it drives
            mark = watch.mark() if watch is not None else 0
            t0 = time.monotonic()
            red.stop(row["tag"])
            out["reply"].append(time.monotonic() - t0)
            if watch is not None:
                t_zero = watch.wait(is_zero, 5, "zero Twist after stop", since=mark)[0]
                out["zero"].append(t_zero - t0)
    finally:
        if watch is not None:
            watch.close()
        for c in match.clients:
            c.close()
        stop_all(procs)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--stops", type=int, default=60, help="stops per driver (default 60)")
    ap.add_argument("--domain", type=int, default=None, help="ROS 2 domain id (default: one from the pid, 1..100)")
    args = ap.parse_args()
    from robo_comp.robots.ros2.bus import loopback_config

    os.environ["CYCLONEDDS_URI"] = loopback_config()  # nothing leaves the machine
    domain = args.domain if args.domain is not None else 1 + os.getpid() % 100
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))
    sim = run("sim", args.stops, domain)
    ros = run("ros2", args.stops, domain)
    print(f"stops per driver: {args.stops}; ROS 2 domain {domain} on lo")
    print(f"{'':34s} {'p50 ms':>8s} {'p99 ms':>8s} {'max ms':>8s}")
    for name, xs in (("sim: request -> reply", sim["reply"]), ("ros2: request -> reply", ros["reply"]),
                     ("ros2: request -> zero Twist on bus", ros["zero"])):
        print(f"{name:34s} {pct(xs, 50):8.2f} {pct(xs, 99):8.2f} {max(xs) * 1000:8.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

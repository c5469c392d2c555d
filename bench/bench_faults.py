"""Storage-fault figures (issue 20): stop latency while the event log cannot be written, and the
time from the disk having space again to the core writing its log again.

    sudo .venv/bin/python bench/bench_faults.py [--robots 20] [--stops 100] [--rounds 5]

Real processes: the core's state folder on a 16 MiB tmpfs (mounted here: needs root), a robot
host driving ``--robots`` robots; the disk is filled to the last byte, then freed, ``--rounds``
times. Prints stop p50/p99 with the log healthy and during the fault (same run, same robots),
and the resume time of each round.
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from robo_comp.client import Client  # noqa: E402
from robo_comp.errors import RoboCompError, StorageError  # noqa: E402
from robo_comp.launch import start_core, start_robots, stop_all  # noqa: E402


def fill(disk: Path) -> Path:
    """Fill ``disk`` to the last byte with one file."""
    filler = disk / "filler"
    with open(filler, "wb", buffering=0) as f:
        for size in (1 << 20, 65536, 512, 1):
            try:
                while f.write(b"\0" * size):
                    pass
            except OSError:
                pass
    return filler


def stops(c: Client, tags: list[int], n: int) -> list[float]:
    """Milliseconds of ``n`` stops (each robot given a far goal first, when the log allows)."""
    out = []
    for k in range(n):
        tag = tags[k % len(tags)]
        try:
            c.give(tag, "goTo", [15, 10])
        except RoboCompError:
            pass  # E_STORAGE during the fault: the robot may stand still; the stop is timed anyway
        t0 = time.perf_counter()
        c.stop(tag)
        out.append((time.perf_counter() - t0) * 1000)
    return out


def pct(xs: list[float], q: float) -> float:
    s = sorted(xs)
    return s[min(len(s) - 1, int(round(q / 100 * (len(s) - 1))))]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, default=20)
    ap.add_argument("--stops", type=int, default=100)
    ap.add_argument("--rounds", type=int, default=5)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        disk = Path(tmp) / "disk"
        disk.mkdir()
        if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=16m", "tmpfs", str(disk)]).returncode != 0:
            print("bench_faults: cannot mount a tmpfs (needs root); skipped")
            return 0
        procs = []
        try:
            state = disk / "state"
            procs.append(start_core(state, "--heartbeat", "0.5", "--teams", "red"))
            procs.append(start_robots(state, "red", a.robots, "--speed", "2"))
            c = Client(str(state), (state / "teams/red.token").read_text().strip(), timeout=10)
            ref = Client(str(state), (state / "referee.token").read_text().strip(), timeout=10)
            t_end = time.monotonic() + 60
            while len([r for r in c.robots() if r["status"] == "connected"]) < a.robots:
                assert time.monotonic() < t_end, "robots did not register"
                time.sleep(0.2)
            tags = [r["tag"] for r in c.robots()]
            healthy = stops(c, tags, a.stops)
            faulty: list[float] = []
            resumes = []
            for _ in range(a.rounds):
                filler = fill(disk)
                while ref.request("stats")["storage"] is None:  # the next logged event finds the disk full
                    try:
                        c.give(tags[0], "goTo", [2, 2], queue=True)
                    except (StorageError, RoboCompError):
                        pass
                faulty += stops(c, tags, a.stops // a.rounds)
                t0 = time.perf_counter()
                filler.unlink()
                while ref.request("stats")["storage"] is not None:
                    time.sleep(0.005)
                resumes.append((time.perf_counter() - t0) * 1000)
            print(f"{a.robots} robots; stop latency, log healthy: p50 {statistics.median(healthy):.2f} ms  "
                  f"p99 {pct(healthy, 99):.2f} ms (n={len(healthy)})")
            print(f"stop latency during a storage fault: p50 {statistics.median(faulty):.2f} ms  "
                  f"p99 {pct(faulty, 99):.2f} ms (n={len(faulty)}; target: stops served)")
            print(f"resume after space returns, {a.rounds} rounds: " + ", ".join(f"{r:.0f}" for r in resumes)
                  + f" ms (max {max(resumes):.0f} ms; target < 1,000 ms)")
            c.close()
            ref.close()
        finally:
            stop_all(procs)
            subprocess.run(["umount", "-l", str(disk)])
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Fault figures.

    sudo .venv/bin/python bench/bench_faults.py [--robots 20] [--stops 100] [--rounds 5]
        [--flips 100] [--clock-steps] [--skip-storage]

Storage (issue 20): the core's state folder on a 16 MiB tmpfs (mounted here: needs root), a
robot host driving ``--robots`` robots; the disk is filled to the last byte, then freed,
``--rounds`` times. Prints stop p50/p99 with the log healthy and during the fault (same run,
same robots), and the resume time of each round.

Damaged records (issue 32, ``--flips N``): the event log of a synthetic match (the core's own
writer), one byte changed at a random offset (a random bit), a real core restarted on it and
made to log more, N times. Prints the records lost per trial (worst, total), values read back
changed, sequence numbers used twice, and whether the core reported exactly the lost ones.

Clock steps (issue 32, ``--clock-steps``): a scored match on a core under Debian's libfaketime
(wall clock only, as an NTP step): +2 h, kill -9, restart, -1 h, kill -9, restart. Prints the
match clock against the time the match really ran (the outage rule ``pause``).
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
sys.path.insert(0, str(Path(__file__).resolve().parent))  # bench_recovery's synthetic match

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


def flip_trials(trials: int, seed: int = 32) -> None:
    """One changed byte per trial in a match's log, a real core restarted on it (module docstring)."""
    import random
    import shutil

    from bench_recovery import synth_log
    from robo_comp.protocol.logfile import read_log

    rng = random.Random(seed)
    worst = total = silent = reused = exact = 0
    with tempfile.TemporaryDirectory() as tmp:
        clean = Path(tmp) / "clean"
        synth_log(clean, 5, 20)
        orig = {r.seq: r for r in read_log(clean / "events.log")}
        top = max(orig)
        size = (clean / "events.log").stat().st_size
        for k in range(trials):
            state = Path(tmp) / f"t{k}"
            state.mkdir()
            shutil.copyfile(clean / "events.log", state / "events.log")
            off = rng.randrange(size)
            with open(state / "events.log", "r+b") as f:
                f.seek(off)
                b = f.read(1)[0]
                f.seek(off)
                f.write(bytes([b ^ (1 << rng.randrange(8))]))
            core = start_core(state, "--heartbeat", "1", "--teams", "red,blue")
            try:
                ref = Client(str(state), (state / "referee.token").read_text().strip(), timeout=10)
                said = set(ref.request("stats")["recovered"]["lost"])
                ref.request("penalty", team="red", points=-1, reason="after the restart")
                ref.close()
            finally:
                stop_all([core])
            recs = list(read_log(state / "events.log", strict=False))
            seqs = [r.seq for r in recs]
            lost = set(orig) - set(seqs)
            worst = max(worst, len(lost))
            total += len(lost)
            silent += sum(1 for r in recs if r.seq in orig and orig[r.seq] != r)
            reused += len(seqs) - len(set(seqs)) + sum(1 for r in recs if r.seq <= top and r.seq not in orig)
            exact += said == lost
            shutil.rmtree(state)
    print(f"one changed byte at a random offset, {trials} trials ({size / 1e6:.2f} MB log, {len(orig):,} events; a "
          f"real core restarted on each): records lost per trial max {worst} (total {total}; target <= 1), "
          f"values read back changed {silent} (target 0), sequence numbers used twice {reused} (target 0), "
          f"lost records reported exactly {exact}/{trials}")


def clock_steps() -> None:
    """+2 h and -1 h steps of the wall clock with a kill -9 and restart after each (docstring)."""
    import glob
    import os

    lib = glob.glob("/usr/lib/*/faketime/libfaketimeMT.so.1")
    if not lib:
        print("clock steps: libfaketime is not installed (apt-get install faketime); skipped")
        return
    demo = Path(__file__).resolve().parents[1] / "robo_comp" / "world" / "scenarios" / "demo_room.toml"
    with tempfile.TemporaryDirectory() as tmp:
        wall = Path(tmp) / "faketime.rc"
        wall.write_text("+0\n")
        saved = dict(os.environ)
        os.environ.update(LD_PRELOAD=lib[0], FAKETIME_TIMESTAMP_FILE=str(wall), FAKETIME_NO_CACHE="1",
                          FAKETIME_DONT_FAKE_MONOTONIC="1")
        state = Path(tmp) / "state"
        core = start_core(state, "--heartbeat", "0.5", "--scenario", str(demo))
        try:
            ref = Client(str(state), (state / "referee.token").read_text().strip(), timeout=10)
            ref.match("start")
            ref.close()
            since, ran, errors = time.monotonic(), 0.0, []
            for step in ("+7200", "-3600"):
                time.sleep(3.0)
                wall.write_text(step + "\n")
                time.sleep(2.0)
                core.kill()
                core.wait()
                ran += time.monotonic() - since
                time.sleep(2.0)  # the outage
                core = start_core(state)
                since = time.monotonic()
                ref = Client(str(state), (state / "referee.token").read_text().strip(), timeout=10)
                st = ref.score()
                ref.close()
                errors.append(st["elapsed"] - (ran + time.monotonic() - since))
                print(f"after a {step} s wall-clock step and a kill -9/restart: match clock {st['elapsed']:.2f} s, "
                      f"the match ran {ran:.2f} s (phase {st['phase']}; rule '{st['outage']}')")
            print(f"clock steps: match clock minus true running time: "
                  + ", ".join(f"{e:+.2f} s" for e in errors) + " (target within 1 s)")
        finally:
            stop_all([core])
            os.environ.clear()
            os.environ.update(saved)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, default=20)
    ap.add_argument("--stops", type=int, default=100)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--flips", type=int, default=0, help="trials of one changed byte in the log (0: none)")
    ap.add_argument("--clock-steps", action="store_true", help="the match clock across wall-clock steps")
    ap.add_argument("--skip-storage", action="store_true", help="not the storage-fault figures")
    a = ap.parse_args()
    if a.flips:
        flip_trials(a.flips)
    if a.clock_steps:
        clock_steps()
    if a.skip_storage:
        return 0
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

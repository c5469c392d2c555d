"""Benchmarks of the team-code sandbox (see docs/perf-sandbox.md).

    .venv/bin/python bench/bench_sandbox.py [--quick] [--os-layer]
    .venv/bin/python bench/bench_sandbox.py --calls-only --reps 5 --baseline b8bc03a   # issue 31's row
    .venv/bin/python bench/bench_sandbox.py --interleaved --reps 3   # the same, in turns with the bare one

1. upload → checked → available: spawn a sandbox and load ``square.py`` (spawn + compile +
   contract + init), and a warm re-upload (new version into a running child).
2. robot-API round trip from sandboxed team code, with a handler that answers at once:
   the interval between successive calls of ``robot.sense()`` in a loop, seen by the host, in
   the default configuration (the OS layer on, as ``make test`` and a match run it) and without
   rate limit and niceness, beside its peer measured just before: a bare msgpack call and
   answer between two processes over a socketpair (min / median / max, the load average, and
   how many calls the limiter held back: none, for one loop). ``--reps N`` measures both N times.
3. isolation: 4 teams on one host loop; two run RPC loops, one spins forever (killed and
   restarted over and over), one allocates without bound. The RPC rate of the two well-behaved
   teams is compared with an undisturbed run.
4. ``--os-layer`` (instead of 1–3): the cold upload and the robot-API round trip with the OS
   layer on (bubblewrap and the seccomp filter, sandbox/oswall.py and sysfilter.py), with
   bubblewrap but the filter left out, and off, interleaved in the same run.
5. ``--seal`` (instead of 1–3): what the seal against memory addresses (sandbox/determinism.py)
   costs team code: CPU time per operation (best of 3) of attribute writes on a team object,
   set insertions of team objects and of a function, f-strings of a function and dicts keyed
   by a class, run under the policy in a fresh process sealed and in one not sealed.
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import pathlib
import select
import socket
import statistics
import sys
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent))

from robo_comp.sandbox.child import FrameReader, pack  # noqa: E402
from robo_comp.sandbox.parent import (  # noqa: E402
    Limits, Sandbox, SandboxStopped, TaskDone, TaskFailed, poll_many,
)

ROOT = pathlib.Path(__file__).resolve().parent.parent
SQUARE = (ROOT / "team_templates" / "extensions" / "square.py").read_text()


def module(name: str, body: str, tasks: str) -> str:
    return (f'MANIFEST = {{"name": "{name}", "version": "1", "kind": "extension", '
            f'"tasks": {{{tasks}}}}}\n\n{body}\n')


PINGER = module("pinger", "def ping(robot, n):\n    for i in range(n):\n        robot.sense()\n"
                          "    return n", '"ping": {"args": [{"name": "n", "type": "int"}]}')
SPINNER = module("spinner", "def spin(robot):\n    while True:\n        pass",
                 '"spin": {"args": []}')
HOG = module("hog", "def hog(robot):\n    keep = []\n    while True:\n"
                    "        keep.append(bytes(1000000))", '"hog": {"args": []}')


def pct(xs: list[float], p: float) -> float:
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(round(p / 100 * (len(xs) - 1))))]


def bench_upload(n: int, label: str = "") -> None:
    cold, warm = [], []
    for i in range(n):
        t0 = time.perf_counter()
        sb = Sandbox("bench", [1], lambda *a: True)
        sb.load("square.py", SQUARE)
        cold.append(time.perf_counter() - t0)
        src2 = SQUARE.replace('"version": "1.0"', f'"version": "2.{i}"')
        t0 = time.perf_counter()
        sb.load("square.py", src2)
        warm.append(time.perf_counter() - t0)
        sb.close()
    print(f"upload -> checked -> available, cold (spawn + compile + contract + init){label}, n={n}: "
          f"median {statistics.median(cold) * 1e3:.1f} ms, p99 {pct(cold, 99) * 1e3:.1f} ms "
          f"(target < 300 ms)")
    print(f"upload -> checked -> available, warm (new version into a running sandbox), n={n}: "
          f"median {statistics.median(warm) * 1e3:.1f} ms, p99 {pct(warm, 99) * 1e3:.1f} ms")


def _echo_child(sock: socket.socket, other: socket.socket) -> None:
    """The peer: a process that answers length-prefixed msgpack calls over a socketpair, until the
    caller closes its end (``other``, the caller's end a forked child holds a copy of, is closed
    first: else the caller's close would never reach it and the child would outlive the bench)."""
    other.close()
    reader = FrameReader(1 << 20)
    while True:
        data = sock.recv(1 << 16)
        if not data:
            return
        for msg in reader.feed(data):
            sock.sendall(pack({"t": "reply", "c": msg["c"], "ok": True, "v": [1.0, 2.0, 3.0]}))


def load() -> str:
    """The machine's load average (1, 5, 15 minutes), printed with every figure."""
    import os

    return "load " + " ".join(f"{x:.2f}" for x in os.getloadavg())


def spread(gaps: list[float]) -> str:
    """min / median / max of ``gaps`` (seconds) in microseconds."""
    return (f"min {min(gaps) * 1e6:.0f} / median {statistics.median(gaps) * 1e6:.0f} / "
            f"max {max(gaps) * 1e6:.0f} us")


BARE_GAPS: list[float] = []


class BareEcho:
    """The peer: a bare msgpack call and answer between two processes over a socketpair (what a
    robot-API call cannot do without: two processes, one message each way)."""

    def __init__(self) -> None:
        self.sock, b = socket.socketpair()
        self.child = mp.Process(target=_echo_child, args=(b, self.sock))
        self.child.start()
        b.close()
        self.reader = FrameReader(1 << 20)
        self.sent = 0

    def run(self, calls: int) -> list[float]:
        """Seconds of each of ``calls`` round trips."""
        a, reader = self.sock, self.reader
        gaps = []
        for _ in range(calls):
            self.sent += 1
            t0 = time.perf_counter()
            a.sendall(pack({"t": "call", "c": self.sent, "r": 1, "g": 1, "n": "sense", "a": []}))
            got: list = []
            while not got:
                got = reader.feed(a.recv(1 << 16))
            gaps.append(time.perf_counter() - t0)
        return gaps

    def close(self) -> None:
        """Close our end; the child sees it and ends (else it is killed: never left behind)."""
        self.sock.close()
        self.child.join(5)
        if self.child.is_alive():
            self.child.kill()
            self.child.join(5)
            print("bench_sandbox: the echo child did not end when its socket closed; killed it", file=sys.stderr)


def bare_round_trip(calls: int) -> float:
    """Median seconds of a bare round trip (:class:`BareEcho`); the gaps are left in ``BARE_GAPS``."""
    echo = BareEcho()
    try:
        gaps = echo.run(calls)
    finally:
        echo.close()
    BARE_GAPS[:] = gaps
    return statistics.median(gaps)


def interleaved(calls: int, chunk: int = 500) -> None:
    """The robot-API round trip (default limits) and the bare one in turns of ``chunk`` calls
    each, so that both see the same moments of a shared machine: min / median / max of each,
    the ratio of the medians, and the CPU time a call costs the host and the sandbox."""
    import resource

    stamps: list[float] = []

    def handler(tag: int, name: str, args: list) -> list[float]:
        stamps.append(time.perf_counter())
        return [1.0, 2.0, 3.0]

    echo = BareEcho()
    sb = Sandbox("bench", [1], handler, Limits())
    bare: list[float] = []
    call: list[float] = []
    host = child = 0.0
    try:
        sb.load("pinger.py", PINGER)
        sb.run_task(1, "ping", [200])  # warm-up
        echo.run(200)
        for _ in range(max(1, calls // chunk)):
            bare += echo.run(chunk)
            stamps.clear()
            c0, r0 = sb.cpu_seconds(), resource.getrusage(resource.RUSAGE_SELF)
            rec = sb.run_task(1, "ping", [chunk])
            r1 = resource.getrusage(resource.RUSAGE_SELF)
            child += sb.cpu_seconds() - c0
            host += r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime
            assert isinstance(rec, TaskDone), rec
            call += [b - a for a, b in zip(stamps, stamps[1:])]
    finally:
        sb.close()
        echo.close()
    n = len(call) + max(1, calls // chunk)
    print(f"bare round trip, {len(bare)} calls: {spread(bare)}")
    print(f"robot-API round trip, default limits (OS layer {'on' if sb.os_sandbox else 'off'}), {len(call)} calls "
          f"in turns of {chunk} with the bare one: {spread(call)}; median "
          f"{statistics.median(call) / statistics.median(bare):.2f}x the bare one (target < 2x), min "
          f"{min(call) / min(bare):.2f}x; CPU a call: host {host / n * 1e6:.1f} us, sandbox {child / n * 1e6:.1f} us; "
          f"calls the limiter held back {sb.paced_calls} ({load()})")


def bench_rpc(calls: int, limits: Limits, label: str, bare: float) -> None:
    """The robot-API round trip of ``calls`` calls of a loop, beside the bare one (``bare``)."""
    import resource

    stamps: list[float] = []

    def handler(tag, name, args):
        stamps.append(time.perf_counter())
        return [1.0, 2.0, 3.0]

    sb = Sandbox("bench", [1], handler, limits)
    sb.load("pinger.py", PINGER)
    sb.run_task(1, "ping", [200])  # warm-up
    stamps.clear()
    child0 = sb.cpu_seconds()
    r0 = resource.getrusage(resource.RUSAGE_SELF)
    rid = sb.start_task(1, "ping", [calls])
    t0 = time.perf_counter()
    done = None
    fd = sb.fileno()
    while done is None:  # a plain host loop: wait on the fd (until the deadline), handle it
        d = sb.deadline()
        r, _, _ = select.select([fd], [], [], 1.0 if d is None else max(0.0, d - time.monotonic()))
        recs = sb.handle_readable() if r else []
        for rec in recs + sb.check_timers():
            if isinstance(rec, (TaskDone, TaskFailed)) and rec.run_id == rid:
                done = rec
    total = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_SELF)
    child_cpu = sb.cpu_seconds() - child0
    sb.close()  # (paced_calls stays readable)
    host_cpu = r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime
    gaps = [b - a for a, b in zip(stamps, stamps[1:])]
    med = statistics.median(gaps)
    print(f"robot-API round trip (team code -> host handler -> team code), {label}, {len(gaps)} calls: "
          f"{spread(gaps)}, median {med / bare:.2f}x the bare round trip, p99 {pct(gaps, 99) * 1e6:.0f} us, "
          f"mean {total / calls * 1e6:.0f} us, {calls / total:,.0f} calls/s, CPU a call: host "
          f"{host_cpu / calls * 1e6:.1f} us, sandbox {child_cpu / calls * 1e6:.1f} us; calls the limiter held back "
          f"{sb.paced_calls} (target median < 2x the bare one; {load()})")


BASELINE_RPC = r'''
import resource, select, statistics, sys, time
sys.path.insert(0, sys.argv[1])
import robo_comp
assert robo_comp.__file__.startswith(sys.argv[1]), robo_comp.__file__
from robo_comp.sandbox.parent import Limits, Sandbox, TaskDone, TaskFailed
calls = int(sys.argv[2])
stamps = []
def handler(tag, name, args):
    stamps.append(time.perf_counter())
    return [1.0, 2.0, 3.0]
sb = Sandbox("bench", [1], handler, Limits())
sb.load("pinger.py", sys.argv[3])
sb.run_task(1, "ping", [200])
stamps.clear()
c0 = sb.cpu_seconds()
r0 = resource.getrusage(resource.RUSAGE_SELF)
rid = sb.start_task(1, "ping", [calls])
fd, done = sb.fileno(), None
while done is None:
    d = sb.deadline()
    r, _, _ = select.select([fd], [], [], 1.0 if d is None else max(0.0, d - time.monotonic()))
    for rec in (sb.handle_readable() if r else []) + sb.check_timers():
        if isinstance(rec, (TaskDone, TaskFailed)) and rec.run_id == rid:
            done = rec
r1 = resource.getrusage(resource.RUSAGE_SELF)
c1 = sb.cpu_seconds()
sb.close()
gaps = [b - a for a, b in zip(stamps, stamps[1:])]
print(min(gaps), statistics.median(gaps), max(gaps), (r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime) / calls,
      (c1 - c0) / calls)
'''


def export_tree(ref: str) -> str:
    """``robo_comp`` of git revision ``ref`` in a temporary folder (its sandbox child runs from there)."""
    import subprocess
    import tempfile

    where = tempfile.mkdtemp(prefix="bench-sandbox-baseline-")
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", ref, "robo_comp"], capture_output=True, check=True)
    subprocess.run(["tar", "-x", "-C", where], input=archive.stdout, check=True)
    return where


def baseline_rpc(tree: str, ref: str, calls: int, bare: float) -> None:
    """The same round trip (default limits) with the code of ``ref``, in a process of its own."""
    import subprocess

    out = subprocess.run([sys.executable, "-c", BASELINE_RPC, tree, str(calls), PINGER], capture_output=True,
                         text=True, check=True)
    lo, med, hi, host, child = (float(x) for x in out.stdout.split()[-5:])
    print(f"  the same before ({ref}), default limits: min {lo * 1e6:.0f} / median {med * 1e6:.0f} / max "
          f"{hi * 1e6:.0f} us, median {med / bare:.2f}x the bare round trip, CPU a call: host {host * 1e6:.1f} us, "
          f"sandbox {child * 1e6:.1f} us ({load()})")


def rpc_rate(seconds: float, disturb: bool, rate: float) -> tuple[list[float], dict[str, int]]:
    """Calls/s of two pinging teams over ``seconds``, with or without two hostile teams."""
    counts = {"a": 0, "b": 0}
    limits = Limits(cpu_seconds=2, wall_seconds=1.0, memory_mib=256, rpc_per_second=rate,
                    max_respawns=100)

    def counter(key):
        def handler(tag, name, args):
            counts[key] += 1
            return [1.0]
        return handler

    good = {"a": Sandbox("a", [1], counter("a"), limits), "b": Sandbox("b", [2], counter("b"), limits)}
    good["a"].load("pinger.py", PINGER)
    good["b"].load("pinger.py", PINGER)
    bad: dict[str, Sandbox] = {}
    if disturb:
        bad["spin"] = Sandbox("c", [3], lambda *a: True, limits)
        bad["spin"].load("spinner.py", SPINNER)
        bad["hog"] = Sandbox("d", [4], lambda *a: True, limits)
        bad["hog"].load("hog.py", HOG)
    boxes = list(good.values()) + list(bad.values())
    tags = {"a": 1, "b": 2, "spin": 3, "hog": 4}
    tasks = {"spin": "spin", "hog": "hog"}
    runs = {}
    for k, sb in good.items():  # run ids are per sandbox: key by (sandbox, run id)
        runs[sb, sb.start_task(tags[k], "ping", [10**6])] = k
    for k, sb in bad.items():
        runs[sb, sb.start_task(tags[k], tasks[k], [])] = k
    stats = {"failed": 0, "kills": 0}
    time.sleep(0.3)
    for k in counts:
        counts[k] = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        for sb, rec in poll_many(boxes, 0.05):
            if isinstance(rec, SandboxStopped):
                stats["kills"] += 1
            if isinstance(rec, TaskFailed) and runs.get((sb, rec.run_id)) in bad:
                k = runs.pop((sb, rec.run_id))
                stats["failed"] += 1
                if bad[k].sock is not None:  # keep disturbing (until it gives up respawning)
                    runs[sb, bad[k].start_task(tags[k], tasks[k], [])] = k
    elapsed = time.perf_counter() - t0
    rates = [counts["a"] / elapsed, counts["b"] / elapsed]
    for sb in boxes:
        sb.close()
    return rates, stats


def bench_isolation(seconds: float) -> None:
    for rate in (0.0, Limits().rpc_per_second):
        base, _ = rpc_rate(seconds, disturb=False, rate=rate)
        hit, stats = rpc_rate(seconds, disturb=True, rate=rate)
        worst = min(h / b for h, b in zip(hit, base))
        print(f"isolation, {seconds:g} s each, rpc limit {rate or 'off'}: undisturbed "
              f"{base[0]:,.0f} / {base[1]:,.0f} calls/s; with a spinning and a hogging team "
              f"{hit[0]:,.0f} / {hit[1]:,.0f} calls/s (worst {worst * 100:.0f}% of undisturbed; "
              f"hostile runs failed {stats['failed']} times, child killed {stats['kills']} times)")


def bench_os_layer(calls: int, n: int) -> None:
    """Upload and robot-API call cost with the OS layer on (bwrap and the seccomp filter), with
    bwrap but the filter left out, and off, interleaved in this one run."""
    import os

    from robo_comp.sandbox import oswall

    def unfiltered(pkg_root: str) -> oswall.Wall | None:
        return oswall.Wall(pkg_root, None) if oswall.enabled() else None

    with_filter = oswall.wall
    bare = bare_round_trip(calls)
    print(f"bare msgpack round trip between two processes over a socketpair, {calls} calls: median {bare * 1e6:.0f} us")
    settings = (("on", with_filter, "on (bwrap + seccomp)"), ("on", unfiltered, "bwrap, no seccomp"),
                ("off", with_filter, "off"))
    for _ in range(2):  # interleaved: a drift of the machine hits every setting alike
        for env, wall, name in settings:
            os.environ[oswall.ENV] = env
            oswall.wall = wall  # the filter left out for one setting only
            label = f"OS layer {name}"
            print(f"-- {label}; load: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}")
            bench_upload(n, f", {label}")
            bench_rpc(calls, Limits(), f"default limits, {label}", bare)
    oswall.wall = with_filter


SEAL_CODE = r'''
import sys, time
if sys.argv[1] == "sealed":
    from robo_comp.sandbox.determinism import seal
    seal()
from robo_comp.sandbox.policy import Policy, compile_team
SRC = """
class Thing:
    def __init__(self):
        self.n = 0
def helper():
    return 0
def writes(n):
    t = Thing()
    for i in range(n):
        t.n = i
def team_set(n):
    s = set()
    objs = [Thing() for i in range(100)]
    for i in range(n):
        s.add(objs[i % 100])
def function_set(n):
    s = set()
    for i in range(n):
        s.add(helper)
def fstring(n):
    for i in range(n):
        x = f"{helper}"
def class_key(n):
    for i in range(n):
        d = {int: 1}
"""
g = Policy(0, lambda t: None).make_globals("team.b")
exec(compile_team(SRC, "b.py"), g)
n = int(sys.argv[2])
for name in ("writes", "team_set", "function_set", "fstring", "class_key"):
    best = float("inf")
    for _ in range(3):
        t = time.process_time()
        g[name](n)
        best = min(best, time.process_time() - t)
    print(name, best / n * 1e9)
'''


def bench_seal(n: int) -> None:
    """CPU ns per operation of team code in a sealed and in an unsealed process."""
    import subprocess

    got: dict[str, dict[str, float]] = {}
    for mode in ("not-sealed", "sealed"):
        out = subprocess.run([sys.executable, "-s", "-P", "-B", "-c", SEAL_CODE, mode, str(n)],
                             capture_output=True, text=True, check=True, cwd=ROOT)
        got[mode] = {k: float(v) for k, v in (line.split() for line in out.stdout.splitlines())}
    print(f"seal cost, CPU ns per operation (best of 3 x {n}):")
    for name in got["sealed"]:
        a, b = got["not-sealed"][name], got["sealed"][name]
        print(f"  {name:13} not sealed {a:6.0f}  sealed {b:6.0f}  ({b - a:+.0f} ns)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repetitions")
    ap.add_argument("--os-layer", action="store_true",
                    help="only the upload and the robot-API call, with the OS layer on and off")
    ap.add_argument("--seal", action="store_true", help="only what the seal against memory addresses costs")
    ap.add_argument("--calls-only", action="store_true", help="only the robot-API round trip beside the bare one")
    ap.add_argument("--interleaved", action="store_true",
                    help="only the robot-API round trip and the bare one, in turns of 500 calls each")
    ap.add_argument("--reps", type=int, default=1, help="times to measure the round trips (each beside a fresh bare one)")
    ap.add_argument("--baseline", metavar="REF", help="also the round trip of git revision REF (e.g. main), in the same run")
    opts = ap.parse_args()
    if opts.seal:
        bench_seal(50_000 if opts.quick else 200_000)
        return
    if opts.os_layer:
        bench_os_layer(2000 if opts.quick else 20000, 5 if opts.quick else 20)
        return
    calls = 2000 if opts.quick else 20000
    if opts.interleaved:
        for _ in range(opts.reps):
            interleaved(calls)
        return
    if not opts.calls_only:
        bench_upload(5 if opts.quick else 20)
    tree = export_tree(opts.baseline) if opts.baseline else None
    for _ in range(opts.reps):  # each figure beside its peer measured just before it
        bare = bare_round_trip(calls)
        print(f"bare msgpack round trip between two processes over a socketpair, {calls} calls: "
              f"{spread(BARE_GAPS)} ({load()})")
        bench_rpc(calls, Limits(), "default limits", bare)
        if tree is not None:
            baseline_rpc(tree, opts.baseline, calls, bare)
        bench_rpc(calls, Limits(rpc_per_second=0, nice=0), "no rate limit, not niced", bare)
    if tree is not None:
        import shutil

        shutil.rmtree(tree, ignore_errors=True)
    if not opts.calls_only:
        bench_isolation(2.0 if opts.quick else 6.0)


if __name__ == "__main__":
    main()

"""What one connection *with* a valid token can make the core hold with a multipart message it
never finishes (docs/security.md, "What remains, exactly"), before and after the core weighed each
connection's bytes (``core/guard.py``), in one run.

    .venv/bin/python bench/bench_unfinished_message.py [--mib 256] [--baseline REV] [--shapes ...] [--cost]

Real core processes (``robo-comp core``): this tree's, and ``--baseline``'s (default
``6cadcd9``, main before the bound; ``''`` skips it), exported with ``git archive``. A raw ZMTP
peer in this process completes the PLAIN handshake with red's valid token, then sends parts of
one message with MORE set and never the last part, up to ``--mib`` MiB on the wire or until the
core cuts it. Shapes: parts of 512 KiB and 1 MiB (under ZMQ_MAXMSGSIZE, 1 MiB + 64 KiB) as fast
as it can; 2 MiB (over it); empty parts (2 bytes each on the wire, the most parts per byte); and
40-byte parts sent one at a time (``--paced`` µs apart), so that libzmq reads each alone. Printed
per shape: what the peer sent before the cut, and the core's peak resident memory above its
baseline (``VmHWM``, reset before each attack; so a bound that held only between two samples
still shows) and what it still held after the peer closed.

``--cost`` measures instead what the bound costs, in this process with real sockets: the core's
count of each message it receives (``ConnectionGuard.took``, ZMQ_SRCFD included) in ns per
message, against the same receive loop without it (best of 7, interleaved); one look at
``--connections`` connections (the kernel's counters of each) in µs per connection; and the CPU
an idle core uses with 20 idle clients connected (its loop now wakes every 10 ms to glance at its
memory), this tree's core and ``--baseline``'s, interleaved.
"""
from __future__ import annotations

import argparse
import os
import pathlib
import socket
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent))

import zmq  # noqa: E402

from robo_comp.launch import stop_all  # noqa: E402
from robo_comp.protocol import wire  # noqa: E402
from robo_comp.testing.zmtp import (  # noqa: E402
    core_peak, core_rss, reset_core_peak, router_address, zmtp_frame, zmtp_plain_handshake,
)

ROOT = pathlib.Path(__file__).resolve().parents[1]
#: main before the bound on what a connection holds (merge of the branch that measured the gap).
BASELINE_REV = "6cadcd9"
MiB = 1 << 20
SHAPES = {"512k": (512 << 10, 0), "1m": (wire.MAX_FRAME, 0), "2m": (2 * MiB, 0), "empty": (0, 0), "paced40": (40, 1)}


def export(rev: str, tmp: pathlib.Path) -> pathlib.Path:
    """The ``robo_comp`` of git revision ``rev`` in a folder under ``tmp``."""
    old = tmp / "baseline"
    old.mkdir()
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "robo_comp"], capture_output=True,
                             check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(old)], input=archive, check=True)
    return old


def start_core(tree: pathlib.Path, state: pathlib.Path) -> subprocess.Popen[bytes]:
    """``robo-comp core`` of the ``robo_comp`` in ``tree`` (this tree or an exported one)."""
    state.mkdir(parents=True)
    with open(state / "core.log", "ab") as log:
        proc = subprocess.Popen([sys.executable, "-m", "robo_comp.cli", "core", "--state", str(state), "--port", "0",
                                 "--teams", "red,blue"], stdout=log, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, cwd=str(tree), env=dict(os.environ, PYTHONPATH=str(tree)))
    t_end = time.monotonic() + 30
    while not (state / "core.json").exists():
        if proc.poll() is not None or time.monotonic() > t_end:
            proc.kill()
            raise RuntimeError(f"the core of {tree} did not start: {(state / 'core.log').read_text()[-2000:]}")
        time.sleep(0.05)
    return proc


def attack(state: pathlib.Path, token: bytes, part: int, total: int, paced_us: float) -> str:
    """One connection's unfinished message of up to ``total`` bytes on the wire in parts of ``part`` bytes."""
    time.sleep(0.3)  # what an earlier attack held is freed
    base = core_rss(state)
    reset_core_peak(state)
    s = socket.create_connection(router_address(state), timeout=10)
    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    zmtp_plain_handshake(s, token)
    frame = zmtp_frame(b"\x01" * part, more=True)
    sent, cut = 0, False
    t0 = time.perf_counter()
    try:
        if paced_us:  # one part per send, apart: libzmq reads each alone
            while sent < total:
                s.send(frame)
                sent += len(frame)
                t = time.perf_counter()
                while time.perf_counter() - t < paced_us / 1e6:
                    pass
        else:
            chunk = frame * max(1, (256 << 10) // len(frame))
            while sent < total:
                s.sendall(chunk)
                sent += len(chunk)
    except OSError:
        cut = True
    seconds = time.perf_counter() - t0
    time.sleep(0.5)  # the core's I/O thread takes in what reached it
    peak = core_peak(state) - base
    if not cut:  # all of it sent: did the core cut it afterwards?
        s.settimeout(0.5)
        try:
            cut = s.recv(1) == b""
        except TimeoutError:
            pass
        except OSError:
            cut = True
    s.close()
    time.sleep(1.0)
    after = core_rss(state) - base
    shown = f"{part // 1024:,} KiB" if part >= 1024 else f"{part} B"
    return (f"parts of {shown}{' one per send' if paced_us else ''}: the peer sent {sent / MiB:,.1f} MiB "
            f"in {seconds:.2f} s, {'and the core cut it' if cut else 'never cut'}; the core's peak "
            f"{round(peak / MiB):+,d} MiB, {round(after / MiB):+,d} MiB after the peer closed")


def run(name: str, tree: pathlib.Path, tmp: pathlib.Path, shapes: list[str], total: int, paced_us: float) -> None:
    state = tmp / f"state-{name}"
    core = start_core(tree, state)
    try:
        token = (state / "teams" / "red.token").read_text().strip().encode()
        for shape in shapes:
            part, paced = SHAPES[shape]
            # paced parts are slow to send: 4 MiB of them is 100,000 parts
            limit = min(total, 4 * MiB) if paced or part < 1024 else total
            print(f"  {name}: {attack(state, token, part, limit, paced_us if paced else 0)}", flush=True)
    finally:
        stop_all([core])


def cost(connections: int, messages: int) -> None:
    """ns a message of the core's count, µs a connection of a look (see the module's help)."""
    from robo_comp.core.guard import ConnectionGuard, GuardLimits
    ctx = zmq.Context()
    router = ctx.socket(zmq.ROUTER)
    router.setsockopt(zmq.RCVHWM, 0)
    port = router.bind_to_random_port("tcp://127.0.0.1")
    guard = ConnectionGuard.watch(router, port, GuardLimits(connections + 100), hold=True)
    dealers = []
    for _ in range(connections):
        d = ctx.socket(zmq.DEALER)
        d.setsockopt(zmq.SNDHWM, 0)
        d.connect(f"tcp://127.0.0.1:{port}")
        dealers.append(d)
    report = b"\x85" + b"x" * 120  # a report's size

    def receive(count: bool) -> float:
        for i in range(messages):
            dealers[i % connections].send(report)
        t0 = time.perf_counter_ns()
        for _ in range(messages):
            router.poll(5000)
            first = router.recv(zmq.NOBLOCK, copy=False)
            frames = [first.bytes, *router.recv_multipart()] if first.more else [first.bytes]
            if count:
                guard.took(first, frames)
        return (time.perf_counter_ns() - t0) / messages

    receive(True)
    guard.serve()
    looks = []  # first: the runs without the count below leave the guard's counts behind
    for _ in range(20):
        guard.next_sweep = 0.0
        t0 = time.perf_counter_ns()
        guard.sweep(time.monotonic())
        looks.append((time.perf_counter_ns() - t0) / 1000 / max(1, len(guard.holding)))
    assert guard.cut_total == 0, "the look cut a connection that held nothing"
    runs: dict[bool, list[float]] = {False: [], True: []}
    for _ in range(7):
        for count in (False, True):
            runs[count].append(receive(count))
    plain, counted = min(runs[False]), min(runs[True])
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"the core's receive loop, {messages:,} messages of {len(report)} bytes over {connections} connections, best "
          f"of 7: {plain:,.0f} ns a message without the count, {counted:,.0f} ns with it ({counted - plain:+,.0f} ns); "
          f"one look at {len(guard.holding)} connections: {min(looks):.2f} µs a connection (median "
          f"{sorted(looks)[len(looks) // 2]:.2f}); load {load}")
    guard.close()
    for d in dealers:
        d.close(0)
    router.close(0)
    ctx.term()


def idle_cpu(tree: pathlib.Path, tmp: pathlib.Path, name: str, seconds: float = 10.0) -> float:
    """CPU milliseconds a second of the core of ``tree``, idle, with 20 idle clients connected."""
    from robo_comp.client import Client
    state = tmp / f"idle-{name}"
    core = start_core(tree, state)
    try:
        token = (state / "teams" / "red.token").read_text().strip()
        clients = [Client(str(state), token) for _ in range(20)]
        for c in clients:
            c.connect()
        time.sleep(1.0)
        pid = core.pid

        def cpu() -> float:
            fields = pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
            return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

        c0, t0 = cpu(), time.monotonic()
        time.sleep(seconds)
        used = (cpu() - c0) / (time.monotonic() - t0) * 1000
        for c in clients:
            c.close()
        return used
    finally:
        stop_all([core])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mib", type=int, default=256, help="MiB of the unfinished message at most (default 256; "
                                                         "4 for parts under 1 KiB)")
    ap.add_argument("--baseline", default=BASELINE_REV, help="git revision of the 'before' core ('' to skip)")
    ap.add_argument("--shapes", nargs="*", default=list(SHAPES), choices=list(SHAPES))
    ap.add_argument("--paced", type=float, default=20.0, help="µs between two paced parts (default 20)")
    ap.add_argument("--cost", action="store_true", help="measure what the bound costs instead (see above)")
    ap.add_argument("--connections", type=int, default=200, help="connections of --cost (default 200)")
    ap.add_argument("--messages", type=int, default=100_000, help="messages of each --cost run (default 100,000)")
    a = ap.parse_args()
    if a.cost:
        cost(a.connections, a.messages)
        if a.baseline:
            with tempfile.TemporaryDirectory() as tmp_name:
                tmp = pathlib.Path(tmp_name)
                old = export(a.baseline, tmp)
                got: dict[str, list[float]] = {"before": [], "after": []}
                for rep in range(2):
                    for name, tree in ([("before", old), ("after", ROOT)] if rep == 0 else
                                       [("after", ROOT), ("before", old)]):
                        got[name].append(idle_cpu(tree, tmp, f"{name}{rep}"))
                load = " ".join(f"{x:.2f}" for x in os.getloadavg())
                print(f"an idle core with 20 idle clients, CPU ms a second (2 interleaved runs of 10 s each): before "
                      f"({a.baseline}) {', '.join(f'{v:.1f}' for v in got['before'])}; after "
                      f"{', '.join(f'{v:.1f}' for v in got['after'])}; load {load}")
        return 0
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"libzmq {zmq.zmq_version()}, pyzmq {zmq.__version__}; ZMQ_MAXMSGSIZE {wire.SOCKET_MAX_FRAME:,} bytes; "
          f"{os.cpu_count()} CPUs, load {load}")
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = pathlib.Path(tmp_name)
        trees = [("after", ROOT)]
        if a.baseline:
            trees.insert(0, (f"before ({a.baseline})", export(a.baseline, tmp)))
        for name, tree in trees:
            run(name, tree, tmp, a.shapes, a.mib * MiB, a.paced)
    print(f"load at the end {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

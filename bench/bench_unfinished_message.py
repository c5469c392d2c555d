"""What one connection *with* a valid token can make the core hold with a multipart message it
never finishes (docs/security.md, "What remains, exactly"), before and after the core weighed each
connection's bytes (``core/guard.py``), in one run.

    .venv/bin/python bench/bench_unfinished_message.py [--mib 256] [--baseline REV] [--shapes ...]

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
    s.close()
    time.sleep(1.0)
    after = core_rss(state) - base
    shown = f"{part // 1024:,} KiB" if part >= 1024 else f"{part} B"
    return (f"parts of {shown}{' one per send' if paced_us else ''}: the peer sent {sent / MiB:,.1f} MiB "
            f"in {seconds:.2f} s, {'then the core cut it' if cut else 'never cut'}; the core's peak "
            f"{peak / MiB:+,.0f} MiB, {after / MiB:+,.0f} MiB after the peer closed")


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


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mib", type=int, default=256, help="MiB of the unfinished message at most (default 256; "
                                                         "4 for parts under 1 KiB)")
    ap.add_argument("--baseline", default=BASELINE_REV, help="git revision of the 'before' core ('' to skip)")
    ap.add_argument("--shapes", nargs="*", default=list(SHAPES), choices=list(SHAPES))
    ap.add_argument("--paced", type=float, default=20.0, help="µs between two paced parts (default 20)")
    a = ap.parse_args()
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"libzmq {zmq.zmq_version()}, pyzmq {zmq.__version__}; ZMQ_MAXMSGSIZE {wire.SOCKET_MAX_FRAME:,} bytes; "
          f"{os.cpu_count()} CPUs, load {load}")
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = pathlib.Path(tmp_name)
        trees = [("after", ROOT)]
        if a.baseline:
            old = tmp / "baseline"
            old.mkdir()
            archive = subprocess.run(["git", "-C", str(ROOT), "archive", a.baseline, "robo_comp"],
                                     capture_output=True, check=True).stdout
            subprocess.run(["tar", "-x", "-C", str(old)], input=archive, check=True)
            trees.insert(0, (f"before ({a.baseline})", old))
        for name, tree in trees:
            run(name, tree, tmp, a.shapes, a.mib * MiB, a.paced)
    print(f"load at the end {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

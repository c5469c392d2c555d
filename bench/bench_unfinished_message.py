"""What one connection *with* a valid token can make the core hold (docs/security.md, "What
remains, exactly"): does ZMQ_MAXMSGSIZE on the ROUTER bound a whole multipart message, or only
one frame, in this pyzmq/libzmq?

    .venv/bin/python bench/bench_unfinished_message.py [--mib 256]

A real core process (``robo-comp core``); a raw ZMTP peer in this process completes the PLAIN
handshake with red's valid token, then sends parts of one message with MORE set and never the
last part: parts under ZMQ_MAXMSGSIZE (1 MiB + 64 KiB) and over it. Printed per part size: what
the peer could send, whether the core cut the connection, how much its resident memory grew, and what it
still held after the connection closed.
"""
from __future__ import annotations

import argparse
import os
import pathlib
import socket
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent))

import zmq  # noqa: E402

from robo_comp.launch import start_core, stop_all  # noqa: E402
from robo_comp.protocol import wire  # noqa: E402
from robo_comp.testing.zmtp import core_rss, router_address, zmtp_frame, zmtp_plain_handshake  # noqa: E402

MiB = 1 << 20


def attack(state: pathlib.Path, token: bytes, part: int, total: int) -> str:
    """One connection's unfinished message of ``total`` bytes in parts of ``part`` bytes."""
    base = core_rss(state)
    s = socket.create_connection(router_address(state), timeout=10)
    zmtp_plain_handshake(s, token)
    frame = zmtp_frame(b"\0" * part, more=True)
    sent, cut = 0, False
    try:
        while sent < total:
            s.sendall(frame)
            sent += part
    except OSError:
        cut = True
    time.sleep(0.5)  # the core's I/O thread takes in what reached it
    held = core_rss(state) - base
    s.close()
    time.sleep(1.0)
    after = core_rss(state) - base
    return (f"parts of {part // 1024:,} KiB: the peer sent {sent / MiB:.0f} MiB of one unfinished message, "
            f"{'and the core cut it' if cut else 'and the core never cut it'}; the core's memory grew {held / MiB:+.0f} MiB, "
            f"{after / MiB:+.0f} MiB after the peer closed")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mib", type=int, default=256, help="MiB of the unfinished message (default 256)")
    a = ap.parse_args()
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"libzmq {zmq.zmq_version()}, pyzmq {zmq.__version__}; the core's ROUTER has ZMQ_MAXMSGSIZE "
          f"{wire.SOCKET_MAX_FRAME:,} bytes; load {load}")
    with tempfile.TemporaryDirectory() as tmp:
        state = pathlib.Path(tmp) / "state"
        core = start_core(state, "--teams", "red,blue")
        try:
            token = (state / "teams" / "red.token").read_text().strip().encode()
            for part in (512 * 1024, wire.MAX_FRAME, 2 * MiB):
                print(attack(state, token, part, a.mib * MiB))
        finally:
            stop_all([core])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

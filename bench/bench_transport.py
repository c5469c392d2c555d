"""Transport figures (issue 28): the core's memory under the unfinished-multipart attack, its
longest loop turn under frames slow to decode, and report throughput, before/after in one run.

    .venv/bin/python bench/bench_transport.py [--baseline REV] [--attack-mib 256] [--seconds 3] [--robots 100] [--reps 1]

Everything runs as real processes over TCP on localhost: the core (``robo-comp core``) in its own
process, the attacks and the load in this one. The core of git revision ``--baseline`` (default:
main before the transport defences) is exported to a temporary folder, and each figure is
measured against it and against this tree, each in a fresh process whose ``robo_comp`` is that
tree's (``--tree DIR``, the child mode).

- memory: the core's resident memory before and after one raw TCP peer without a credential
  sends ``--attack-mib`` MiB as 8 MiB parts of one multipart message, never the last part;
- loop turn: a console's ``robots`` requests, one after the other, timed while a peer sends 20
  frames under 1 MiB that would each make 300,000 maps (the longest round trip is the longest
  loop turn plus a round trip; the same figure without the attack is printed beside it);
- decoding alone: the tree's ``protocol.decode_envelope`` on one frame under 1 MiB of each shape
  in :func:`decode_shapes` (worst cases for msgpack: many empty maps, lists, nils, short keys;
  and a full 1,000-robot ``reports`` batch), best of 5, in the child process, no sockets;
- throughput: single ``report`` messages absorbed per second from ``--robots`` connections
  (``bench_core.core_rate``).
"""
from __future__ import annotations

import argparse
import json
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TREE = Path(sys.argv[sys.argv.index("--tree") + 1]).resolve() if "--tree" in sys.argv else ROOT
sys.path.insert(0, str(TREE))
sys.path.insert(1, str(ROOT / "bench"))
#: main before the transport defences of issue 28.
BASELINE_REV = "639df49"
MiB = 1 << 20

import zmq  # noqa: E402

from robo_comp import protocol as P  # noqa: E402
from robo_comp.launch import start_core, stop_all  # noqa: E402
from bench_core import _export, _many_robots, core_rate, secure_plain_client  # noqa: E402


def _rss(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    return 0


def _greeting() -> bytes:
    """A ZMTP 3.0 greeting with the NULL mechanism (no credential), then READY as a DEALER."""
    greet = b"\xff" + b"\0" * 8 + b"\x7f" + bytes([3, 0]) + b"NULL".ljust(20, b"\0") + b"\0" + b"\0" * 31
    body = b"\x05READY" + b"\x0bSocket-Type" + (6).to_bytes(4, "big") + b"DEALER"
    return greet + bytes([0x04, len(body)]) + body


def memory_attack(state: Path, mib: int) -> dict[str, float]:
    """The core's RSS (MiB) before and after the unfinished-multipart attack of ``mib`` MiB."""
    info = json.loads((state / "core.json").read_text())
    host, port = info["router"].removeprefix("tcp://").rsplit(":", 1)
    time.sleep(0.5)
    base = _rss(info["pid"])
    s = socket.create_connection((host, int(port)), timeout=10)
    part = 8 * MiB
    frame = bytes([0x03]) + part.to_bytes(8, "big") + b"\0" * part  # MORE | LONG
    sent = 0
    try:
        s.sendall(_greeting())
        while sent < mib * MiB:
            s.sendall(frame)
            sent += part
    except OSError:
        pass
    time.sleep(1.0)
    after = _rss(info["pid"])
    s.close()
    return {"rss_base": base / MiB, "rss_attack": after / MiB, "attack_sent": sent / MiB}


def _dealer(url: str, token: str) -> zmq.Socket:
    d = zmq.Context.instance().socket(zmq.DEALER)
    d.setsockopt(zmq.LINGER, 0)
    d.setsockopt(zmq.ROUTING_ID, P.new_routing_id())
    secure_plain_client(d, token)
    d.connect(url)
    return d


def _probe(url: str, token: str, seconds: float) -> float:
    """The longest round trip (ms) of back-to-back ``robots`` requests for ``seconds``."""
    d = _dealer(url, token)
    d.send(P.request("hello", 1, {"token": token}))
    assert d.poll(10_000), "no hello reply"
    secret = P.unpack(d.recv())["body"].get("session")
    worst = 0.0
    n = 2
    t_end = time.monotonic() + seconds
    while time.monotonic() < t_end:
        t0 = time.perf_counter()
        d.send(P.request("robots", n, {}, secret))
        while True:
            assert d.poll(30_000), "the core stopped answering"
            m = P.unpack(d.recv())
            if m.get("type") == "reply" and m.get("id") == n:
                break
        worst = max(worst, time.perf_counter() - t0)
        n += 1
    d.close(0)
    return worst * 1000


def stall(state: Path, frames: int = 20) -> dict[str, float]:
    """Longest console round trip (ms) without and with ``frames`` slow-to-decode frames sent."""
    url = json.loads((state / "core.json").read_text())["router"]
    blue = (state / "teams/blue.token").read_text().strip()
    red = (state / "teams/red.token").read_text().strip()
    quiet = _probe(url, blue, 2.0)
    attacker = _dealer(url, red)  # a credential, no session (a team's own program gone wrong)
    slow = [P.request("radio", k, {"tag": 1, "data": [{}] * 300_000}) for k in range(frames)]
    result: dict[str, float] = {}
    t = threading.Thread(target=lambda: result.__setitem__("worst", _probe(url, blue, 4.0)))
    t.start()
    time.sleep(0.5)
    for f in slow:
        attacker.send(f)
    answered = 0
    t_end = time.monotonic() + 60
    while answered < frames and time.monotonic() < t_end and attacker.poll(10_000):
        attacker.recv()
        answered += 1
    t.join()
    attacker.close(0)
    return {"turn_quiet_ms": quiet, "turn_attack_ms": result["worst"], "slow_answered": answered}


def decode_shapes() -> dict[str, bytes]:
    """Frames under 1 MiB that msgpack is slowest to decode, and the largest honest one (a
    1,000-robot ``reports`` batch with a sensor map per robot), by name."""
    n = 1000
    reports = {"tags": list(range(1, n + 1)), "x": [2.5] * n, "y": [3.5] * n, "heading": [90.0] * n,
               "moving": [True] * n, "sensors": [{"front": 1.25, "left": 0.5, "right": 2.0}] * n}
    shapes: dict[str, tuple[str, dict[str, object]]] = {
        "500,000 empty maps": ("radio", {"tag": 1, "data": [{}] * 500_000}),
        "16 x 60,000 empty maps": ("radio", {"tag": 1, "data": [[{}] * 60_000 for _ in range(16)]}),
        "500,000 empty lists": ("radio", {"tag": 1, "data": [[]] * 500_000}),
        "900,000 nils": ("radio", {"tag": 1, "data": [None] * 900_000}),
        "200,000 one-key maps": ("radio", {"tag": 1, "data": [{"a": 1}] * 200_000}),
        "1,000-robot reports": ("reports", reports),
    }
    frames = {name: P.request(kind, 1, body) for name, (kind, body) in shapes.items()}
    assert all(len(f) < P.MAX_FRAME for f in frames.values())
    return frames


def decode_times(reps: int = 5) -> dict[str, float]:
    """Best of ``reps`` times (ms) of this tree's ``decode_envelope`` on each of
    :func:`decode_shapes`, whether it decodes the frame or refuses it; ``*_refused`` says which."""
    out: dict[str, float] = {}
    for name, frame in decode_shapes().items():
        best, refused = float("inf"), 0.0
        for _ in range(reps):
            t0 = time.perf_counter()
            try:
                P.decode_envelope(frame)
                refused = 0.0
            except Exception:  # a refusal (E_TOO_LARGE) is the outcome being timed
                refused = 1.0
            best = min(best, time.perf_counter() - t0)
        out[f"decode {name}"] = best * 1000
        out[f"decode {name} refused"] = refused
    return out


def child(a: argparse.Namespace) -> None:
    """Measure this process's tree and print one JSON line."""
    with tempfile.TemporaryDirectory() as tmp:
        state = Path(tmp) / "state"
        proc = start_core(state, *_many_robots(), "--heartbeat", "1.0", "--teams", "red,blue", "--port", "0")
        try:
            out: dict[str, float] = decode_times()
            out["rate"], _ = core_rate(state, a.robots, a.seconds)  # first: it counts the core's errors
            out.update(stall(state))
            out.update(memory_attack(state, a.attack_mib))  # last: the old core keeps what it took
        finally:
            stop_all([proc])
    print(json.dumps(out))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default=BASELINE_REV, help="git revision of the 'before' core")
    ap.add_argument("--attack-mib", type=int, default=256, help="MiB the unfinished message sends")
    ap.add_argument("--seconds", type=float, default=3.0, help="seconds of report load")
    ap.add_argument("--robots", type=int, default=100, help="connections sending reports")
    ap.add_argument("--reps", type=int, default=1, help="interleaved before/after runs (medians are printed)")
    ap.add_argument("--tree", help="child mode: measure the robo_comp of this folder and print JSON")
    a = ap.parse_args()
    if a.tree:
        child(a)
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        old = _export(a.baseline, Path(tmp))
        runs: dict[str, list[dict[str, float]]] = {"before": [], "after": []}
        for k in range(a.reps):
            order = [("before", old), ("after", ROOT)] if k % 2 == 0 else [("after", ROOT), ("before", old)]
            for name, tree in order:
                env = dict(os.environ, PYTHONPATH=str(tree))
                out = subprocess.run([sys.executable, __file__, "--tree", str(tree), "--attack-mib",
                                      str(a.attack_mib), "--seconds", str(a.seconds), "--robots", str(a.robots)],
                                     capture_output=True, text=True, env=env, cwd=str(tree), timeout=900)
                if out.returncode != 0:
                    raise RuntimeError(f"{name} run failed: {out.stderr[-3000:]}")
                runs[name].append(json.loads(out.stdout.strip().splitlines()[-1]))
    b, n = ({key: statistics.median(r[key] for r in rows) for key in rows[0]} for rows in runs.values())
    print(f"transport figures, before = {a.baseline}, after = this tree ({a.reps} interleaved runs each, "
          "medians; same machine, same run):")
    for name, r in (("before", b), ("after", n)):
        print(f"  {name:6s} memory: {r['rss_base']:.0f} MiB -> {r['rss_attack']:.0f} MiB after "
              f"{r['attack_sent']:.0f} MiB of one unfinished message from a peer without a credential "
              f"(+{r['rss_attack'] - r['rss_base']:.0f} MiB; target < +50 MiB)")
    for name, r in (("before", b), ("after", n)):
        print(f"  {name:6s} longest console round trip: {r['turn_quiet_ms']:.1f} ms quiet, "
              f"{r['turn_attack_ms']:.1f} ms under 20 frames of 300,000 maps ({r['slow_answered']:.0f} answered; "
              "target < 50 ms)")
    for key in (k for k in b if k.startswith("decode ") and not k.endswith(" refused")):
        verdict = lambda r: "refused" if r[key + " refused"] else "decoded"  # noqa: E731
        print(f"  {key} (best of 5, one frame): {b[key]:.2f} ms {verdict(b)} before, "
              f"{n[key]:.2f} ms {verdict(n)} after")
    print(f"  reports absorbed ({a.robots} connections): {b['rate']:,.0f} -> {n['rate']:,.0f} msg/s "
          f"({n['rate'] / b['rate'] - 1:+.1%}); every run: "
          + "; ".join(f"{k} " + ", ".join(f"{r['rate']:,.0f}" for r in v) for k, v in runs.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Coverage-guided fuzzing of the protocol decoder and the scenario parser (issue 9, part 4).

    .venv/bin/pip install atheris                       # optional dependency (3.0.0 works on 3.11)
    .venv/bin/python bench/fuzz_atheris.py              # 120 s, both targets
    .venv/bin/python bench/fuzz_atheris.py --seconds 600 --target decode
    .venv/bin/python bench/fuzz_atheris.py --engine simple   # no atheris: our own mutation fuzzer

One input drives one target: ``decode`` feeds the bytes to
:func:`robo_comp.protocol.decode`; ``scenario`` decodes them as UTF-8 (with replacement)
and feeds the text to :func:`robo_comp.world.scenario.parse_scenario`. With ``--target both``
the first byte of the input chooses the target. Only :class:`RoboCompError` subclasses are
acceptable; anything else is a crash: libFuzzer (atheris) prints the traceback and writes the
input to ``--artifacts/crash-*``; the simple engine prints the traceback and the reproducer as
a Python bytes literal. Every crash found becomes a test in ``tests/test_fuzz.py``.

The corpus starts from valid frames of every request type and ``demo_room.toml``.
"""
from __future__ import annotations

import argparse
import os
import random
import sys
import tempfile
import time
import traceback
from pathlib import Path
from typing import Any, Callable

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
DEMO = ROOT / "robo_comp" / "world" / "scenarios" / "demo_room.toml"

try:
    import atheris
except ImportError:  # pragma: no cover - atheris is optional
    atheris = None

if atheris is not None:
    with atheris.instrument_imports(include=["robo_comp", "tomllib"]):
        from robo_comp import protocol as P
        from robo_comp.errors import RoboCompError
        from robo_comp.world.scenario import parse_scenario
else:  # pragma: no cover
    from robo_comp import protocol as P
    from robo_comp.errors import RoboCompError
    from robo_comp.world.scenario import parse_scenario

_COUNT = {"n": 0, "t0": time.monotonic(), "last": time.monotonic()}


def fuzz_decode(data: bytes) -> None:
    """One decoder execution: a Message or a RoboCompError (a batch of reports is also
    checked row by row, as the core does)."""
    try:
        msg = P.decode(data)
        if msg.type == "reports":
            P.check_reports(msg.body)
    except RoboCompError:
        pass


def fuzz_scenario(data: bytes) -> None:
    """One parser execution: a Scenario or a ScenarioError (a RoboCompError)."""
    try:
        parse_scenario(data.decode("utf-8", "replace"), "fuzz.toml", base_dir=DEMO.parent)
    except RoboCompError:
        pass


def fuzz_both(data: bytes) -> None:
    """The first byte picks the target (even: decoder, odd: parser)."""
    if not data:
        return
    (fuzz_decode if data[0] % 2 == 0 else fuzz_scenario)(data[1:])


TARGETS: dict[str, Callable[[bytes], None]] = {"decode": fuzz_decode, "scenario": fuzz_scenario, "both": fuzz_both}


def counted(fn: Callable[[bytes], None]) -> Callable[[bytes], None]:
    """Wrap a target so it prints executions every 10 s."""
    def run(data: bytes) -> None:
        _COUNT["n"] += 1
        now = time.monotonic()
        if now - _COUNT["last"] >= 10.0:
            _COUNT["last"] = now
            print(f"fuzz: {_COUNT['n']} executions in {now - _COUNT['t0']:.0f} s", file=sys.stderr, flush=True)
        fn(data)
    return run


def seeds(target: str) -> list[bytes]:
    """Valid inputs to start from: frames of every request type and the demo scenario."""
    frames = [P.request(t, i + 1, {n: _sample(kind) for n, (kind, _r) in spec.items()})
              for i, (t, spec) in enumerate(sorted(P.REQUESTS.items()))]
    frames += [P.ok_reply(3, {"x": 1.0}), P.pack([1, 2]), b""]
    text = DEMO.read_bytes()
    if target == "decode":
        return frames
    if target == "scenario":
        return [text]
    return [b"\x00" + f for f in frames] + [b"\x01" + text]


def _sample(kind: str) -> Any:
    return {"int": 101, "number": 1.5, "str": "goTo", "bool": True, "list": [3, 4], "map": {"a": 1},
            "bytes": b"\x89PNG", "any": None, "int or nil": None}[kind]


# ---------------------------------------------------------------------------- engines
def run_atheris(target: str, seconds: int, artifacts: Path) -> int:
    """libFuzzer through atheris for ``seconds``; returns only on error (libFuzzer exits)."""
    corpus = Path(tempfile.mkdtemp(prefix=f"rc-fuzz-{target}-"))
    for i, s in enumerate(seeds(target)):
        (corpus / f"seed-{i}").write_bytes(s)
    artifacts.mkdir(parents=True, exist_ok=True)
    argv = [sys.argv[0], str(corpus), f"-max_total_time={seconds}", "-timeout=10", "-rss_limit_mb=2048",
            f"-artifact_prefix={artifacts}/", "-print_final_stats=1", "-max_len=4096"]
    print(f"fuzz: atheris {getattr(atheris, '__version__', '?')}, target {target}, {seconds} s, "
          f"corpus {corpus}", flush=True)
    atheris.Setup(argv, counted(TARGETS[target]))
    atheris.Fuzz()
    return 0


def mutate(data: bytes, rng: random.Random, pool: list[bytes]) -> bytes:
    """One to four byte-level mutations (flip, insert, delete, duplicate, splice, magic values)."""
    b = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        op = rng.randrange(7)
        i = rng.randrange(len(b) + 1)
        if op == 0 and b:
            b[i % len(b)] ^= 1 << rng.randrange(8)
        elif op == 1:
            b[i:i] = bytes([rng.randrange(256)])
        elif op == 2 and b:
            del b[i % len(b):i % len(b) + rng.randint(1, 8)]
        elif op == 3 and b:
            j = rng.randrange(len(b))
            b[i:i] = b[j:j + rng.randint(1, 16)]
        elif op == 4:
            other = rng.choice(pool)
            j = rng.randrange(len(other) + 1)
            b[i:] = other[j:]
        elif op == 5:
            b[i:i] = rng.choice([b"\xc0", b"\xc2", b"\xc3", b"\xcb\x7f\xf8\x00\x00\x00\x00\x00\x00",
                                 b"\xdd\xff\xff\xff\xff", b"\xde\x00\x01", b"\xcf\xff\xff\xff\xff\xff\xff\xff\xff",
                                 b"=", b"[[", b"]]", b'"""', b"\n", b"#", b"\\u", b"nan", b"-inf", b"1e999"])
        elif op == 6 and b:
            k = i % len(b)
            b[k] = rng.choice(b"\x00\xff\x7f\x80 =.#\n\"[]{},0123456789")
    return bytes(b[:4096])


def run_simple(target: str, seconds: int, artifacts: Path, seed: int = 0) -> int:
    """Our own mutation fuzzer (no coverage feedback): mutate seeds and inputs that raised a
    different error than before; print executions and crashes. Returns the number of crashes."""
    rng = random.Random(seed)
    pool = seeds(target)
    fn = TARGETS[target]
    crashes: list[bytes] = []
    n = 0
    t0 = last = time.monotonic()
    seen_msgs: set[str] = set()
    print(f"fuzz: simple mutation engine, target {target}, {seconds} s", flush=True)
    while time.monotonic() - t0 < seconds:
        data = mutate(rng.choice(pool), rng, pool)
        n += 1
        try:
            fn(data)
        except Exception as e:  # a crash: anything but RoboCompError
            key = f"{type(e).__name__}:{traceback.extract_tb(e.__traceback__)[-1].lineno}"
            if key not in seen_msgs:
                seen_msgs.add(key)
                crashes.append(data)
                artifacts.mkdir(parents=True, exist_ok=True)
                (artifacts / f"crash-{len(crashes)}").write_bytes(data)
                print(f"fuzz: CRASH {key}\nreproducer: {data!r}\n{traceback.format_exc()}", flush=True)
            continue
        if rng.random() < 0.01 and len(pool) < 5000:  # keep a few inputs to grow the corpus
            pool.append(data)
        now = time.monotonic()
        if now - last >= 10:
            last = now
            print(f"fuzz: {n} executions in {now - t0:.0f} s", flush=True)
    print(f"fuzz: done: {n} executions in {time.monotonic() - t0:.1f} s "
          f"({n / max(1e-9, time.monotonic() - t0):.0f}/s), {len(crashes)} distinct crash(es)", flush=True)
    return len(crashes)


def main(argv: list[str] | None = None) -> int:
    """Parse options and fuzz."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seconds", type=int, default=120, help="how long to fuzz (default 120)")
    p.add_argument("--target", choices=sorted(TARGETS), default="both")
    p.add_argument("--engine", choices=("atheris", "simple"), default="atheris" if atheris else "simple",
                   help="atheris (libFuzzer, coverage-guided; default when installed) or simple")
    p.add_argument("--artifacts", type=Path, default=Path(tempfile.gettempdir()) / "rc-fuzz-artifacts",
                   help="where crashing inputs are written")
    args = p.parse_args(argv)
    os.environ.setdefault("PYTHONHASHSEED", "0")
    if args.engine == "atheris":
        if atheris is None:
            raise SystemExit("atheris is not installed: .venv/bin/pip install atheris, or use --engine simple")
        return run_atheris(args.target, args.seconds, args.artifacts)
    return 1 if run_simple(args.target, args.seconds, args.artifacts) else 0


if __name__ == "__main__":
    raise SystemExit(main())

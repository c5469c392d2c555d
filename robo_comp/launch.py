"""Start the core and robot hosts as real processes (used by the demo, tests and benchmarks).

Their output goes to log files in the state folder (``core.log``, ``robots-<team>.log``), never
to a pipe nobody reads (a full pipe would block the child).
"""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path


def _spawn(args: list[str], log: Path) -> subprocess.Popen[bytes]:
    with open(log, "ab") as f:
        return subprocess.Popen([sys.executable, "-m", "robo_comp.cli", *args],
                                stdout=f, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)


def start_core(state: Path, *extra: str, port: int = 0, wait: float = 20.0) -> subprocess.Popen[bytes]:
    """Start ``robo-comp core`` (on a free port by default) and wait for a fresh ``core.json``."""
    state.mkdir(parents=True, exist_ok=True)
    info = state / "core.json"
    info.unlink(missing_ok=True)
    proc = _spawn(["core", "--state", str(state), "--port", str(port), *extra], state / "core.log")
    t_end = time.monotonic() + wait
    while not info.exists():
        if proc.poll() is not None:
            raise RuntimeError(f"core exited with {proc.returncode}: {(state / 'core.log').read_text()[-2000:]}")
        if time.monotonic() > t_end:
            proc.kill()
            raise RuntimeError(f"core did not start within {wait:.0f} s")
        time.sleep(0.02)
    return proc


def start_robots(state: Path, team: str, count: int, *extra: str) -> subprocess.Popen[bytes]:
    """Start ``robo-comp robots`` for ``team`` against the core whose state folder is ``state``, with
    the organiser's host token for that team (``STATE/hosts/<team>.token``)."""
    return _spawn(["robots", "--core", str(state), "--token-file", str(state / "hosts" / f"{team}.token"),
                   "--count", str(count), *extra], state / f"robots-{team}.log")


def stop_all(procs: list[subprocess.Popen[bytes]], timeout: float = 5.0) -> None:
    """Terminate processes (newest first) and reap them; kill those that do not exit."""
    for p in reversed(procs):
        if p.poll() is None:
            p.terminate()
    for p in procs:
        try:
            p.wait(timeout)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()

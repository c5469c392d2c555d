"""Shared fixtures: a real core process and real robot-host processes on localhost."""
from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from subprocess import Popen
from typing import Any

import pytest

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

from robo_comp.client import Client  # noqa: E402
from robo_comp.launch import start_core, start_robots, stop_all  # noqa: E402

HEARTBEAT = 0.2


@dataclass
class CoreHandle:
    """A running core process and how to reach it."""

    state: Path
    proc: Popen[bytes]
    procs: list[Popen[bytes]] = field(default_factory=list)
    clients: list[Client] = field(default_factory=list)

    def token(self, team: str) -> str:
        """A team's token (``referee`` for the referee's)."""
        path = self.state / ("referee.token" if team == "referee" else f"teams/{team}.token")
        return path.read_text().strip()

    def client(self, team: str, **kw: Any) -> Client:
        """A connected client for ``team`` (closed at teardown)."""
        c = Client(str(self.state), self.token(team), **kw)
        self.clients.append(c)
        return c

    def robots(self, team: str, count: int, *extra: str) -> Popen[bytes]:
        """Start a robot host process (stopped at teardown)."""
        p = start_robots(self.state, team, count, *extra)
        self.procs.append(p)
        return p


def wait_for(pred: Callable[[], Any], timeout: float = 10.0, what: str = "condition") -> Any:
    """Poll ``pred`` until it returns a truthy value; fail the test after ``timeout`` s."""
    t_end = time.monotonic() + timeout
    while True:
        v = pred()
        if v:
            return v
        if time.monotonic() > t_end:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.05)


def wait_robots(c: Client, n: int, status: str = "connected", timeout: float = 15.0) -> list[dict[str, Any]]:
    """Wait until ``c`` sees ``n`` robots with ``status``; return them sorted by tag."""
    return wait_for(lambda: (lambda rows: sorted(rows, key=lambda r: r["tag"])
                             if sum(r["status"] == status for r in rows) >= n else None)(c.robots()),
                    timeout, f"{n} {status} robots")


def next_event_where(c: Client, pred: Callable[[dict[str, Any]], bool], timeout: float = 10.0) -> dict[str, Any]:
    """Read watched events until one matches ``pred``."""
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        ev = c.next_event(0.2)
        if ev is not None and pred(ev):
            return ev
    raise AssertionError("timed out waiting for a matching event")


@pytest.fixture(scope="session", autouse=True)
def compiled_planner() -> None:
    """Compile the planner's numba kernels once, into their on-disk cache, before any robot
    process starts (a cold compile takes seconds; every later process loads the cache)."""
    from robo_comp.world.planner import warm_up

    warm_up()


@pytest.fixture
def core(tmp_path: Path, request: pytest.FixtureRequest) -> Iterator[CoreHandle]:
    """A core process with teams red and blue and a fast heartbeat (0.2 s).

    ``@pytest.mark.heartbeat(S)`` sets another interval (for tests driving raw sockets).
    """
    state = tmp_path / "state"
    mark = request.node.get_closest_marker("heartbeat")
    hb = mark.args[0] if mark else HEARTBEAT
    proc = start_core(state, "--heartbeat", str(hb), "--teams", "red,blue")
    h = CoreHandle(state, proc)
    yield h
    for c in h.clients:
        c.close()
    stop_all([h.proc, *h.procs])


def pytest_configure(config: pytest.Config) -> None:
    """Register markers and let cores started by tests import test-only plugins."""
    config.addinivalue_line("markers", "rules(spec): scoring rules plugin of the match fixture")
    here = str(Path(__file__).parent)
    os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [here, os.environ.get("PYTHONPATH")]))

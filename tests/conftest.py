"""Shared fixtures: a real core process and real robot-host processes on localhost."""
from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from subprocess import Popen
from typing import Any

import pytest

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

from robo_comp.client import Client  # noqa: E402
from robo_comp.launch import start_core, start_robots, stop_all  # noqa: E402
from robo_comp.testing import next_event_where, wait_for, wait_robots  # noqa: E402,F401  (tests import them from here)

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


@pytest.fixture(scope="session", autouse=True)
def compiled_planner() -> None:
    """Compile the planner's numba kernels once, into their on-disk cache, before any robot
    process starts (a cold compile takes seconds; every later process loads the cache)."""
    from robo_comp.world.planner import warm_up

    warm_up()


@pytest.fixture
def core(tmp_path: Path, request: pytest.FixtureRequest) -> Iterator[CoreHandle]:
    """A core process with teams red and blue and a fast heartbeat (0.2 s).

    ``@pytest.mark.heartbeat(S)`` sets another interval (for tests driving raw sockets);
    ``@pytest.mark.core_args(*ARGS)`` adds options to ``robo-comp core``.
    """
    state = tmp_path / "state"
    mark = request.node.get_closest_marker("heartbeat")
    hb = mark.args[0] if mark else HEARTBEAT
    extra = request.node.get_closest_marker("core_args")
    proc = start_core(state, "--heartbeat", str(hb), "--teams", "red,blue", *(extra.args if extra else ()))
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

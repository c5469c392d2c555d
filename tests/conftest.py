"""Shared fixtures: a real core process and real robot-host processes on localhost."""
from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

from robo_comp.protocol import check_event  # noqa: E402
from robo_comp.launch import start_core  # noqa: E402
from robo_comp.testing import Match, next_event_where, wait_for, wait_robots  # noqa: E402,F401  (tests import them from here)

HEARTBEAT = 0.2


#: A running core process, its robot hosts and clients: the pytest plugin's :class:`Match`
#: (``CoreHandle(state, None, proc)``; ``close()`` stops it all).
CoreHandle = Match


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
    h = CoreHandle(state, None, proc)
    yield h
    h.close()
    wrong = sorted({why for e in h.logged_events() if (why := check_event(e["topic"], e["data"]))})
    assert not wrong, f"the core logged events that protocol/topics.py's table does not describe: {wrong}"


def pytest_configure(config: pytest.Config) -> None:
    """Register markers and let cores started by tests import test-only plugins."""
    config.addinivalue_line("markers", "rules(spec): scoring rules plugin of the match fixture")
    here = str(Path(__file__).parent)
    os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [here, os.environ.get("PYTHONPATH")]))

"""The pytest plugin of robo_comp (entry point ``pytest11``): options and fixtures.

See :mod:`robo_comp.testing` for what the fixtures give.
"""
from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

from robo_comp.testing.match import Match, start_match
from robo_comp.world.scenario import DEFAULT_SCENARIO, resolve_scenario

if TYPE_CHECKING:
    from robo_comp.engine.bench import Bench


# ---------------------------------------------------------------------- pytest hooks and fixtures
def pytest_addoption(parser: pytest.Parser) -> None:
    """``--robo-scenario`` / ``--robo-team`` and their ini forms."""
    group = parser.getgroup("robo_comp", "robo_comp match and bench fixtures")
    group.addoption("--robo-scenario", default=None,
                    help="scenario file (or bundled scenario name) for robo_match/robo_bench")
    group.addoption("--robo-team", default=None, help="the team robo_bench plays for")
    parser.addini("robo_comp_scenario", "scenario file or bundled name for the robo_comp fixtures",
                  default=DEFAULT_SCENARIO)
    parser.addini("robo_comp_team", "team name for the robo_comp fixtures (default: the scenario's first)",
                  default="")


#: Why the tests run team code without the OS sandbox (None: they run it inside).
OS_SANDBOX_OFF: str | None = None


def pytest_configure(config: pytest.Config) -> None:
    """Register the ``slow`` marker used by team tests that run a real match; on a machine
    without the OS sandbox (bubblewrap: a student's laptop), run the tests' team code without it
    (``ROBO_COMP_OS_SANDBOX=off``) and say so in the header, rather than refuse every test."""
    global OS_SANDBOX_OFF
    config.addinivalue_line("markers", "slow: long-running tests (deselect with -m 'not slow')")
    import os

    import robo_comp
    from robo_comp.errors import RoboCompError
    from robo_comp.sandbox import oswall

    if not oswall.enabled():
        OS_SANDBOX_OFF = f"{oswall.ENV}=off in the environment"
        return
    try:
        oswall.check(str(Path(robo_comp.__file__).resolve().parent.parent))
    except RoboCompError as e:
        OS_SANDBOX_OFF = str(e.details.get("why", e.message))
        os.environ[oswall.ENV] = "off"


def pytest_report_header(config: pytest.Config) -> str:
    """Whether team code in these tests runs inside the OS sandbox."""
    if OS_SANDBOX_OFF is None:
        return "robo_comp: team code runs inside the OS sandbox (bubblewrap and a seccomp filter)"
    return f"robo_comp: team code runs WITHOUT the OS sandbox ({OS_SANDBOX_OFF})"


@pytest.fixture(scope="session")
def robo_scenario(pytestconfig: pytest.Config) -> Path:
    """The scenario file the robo_comp fixtures use (see the module docstring)."""
    spec = pytestconfig.getoption("--robo-scenario") or pytestconfig.getini("robo_comp_scenario") or DEFAULT_SCENARIO
    return resolve_scenario(spec, Path(str(pytestconfig.rootpath)))


@pytest.fixture(scope="session")
def robo_team(pytestconfig: pytest.Config, robo_scenario: Path) -> str:
    """The team the tests play for."""
    name = pytestconfig.getoption("--robo-team") or pytestconfig.getini("robo_comp_team")
    if name:
        return str(name)
    from robo_comp.world.scenario import load_scenario

    teams = [t.name for t in load_scenario(robo_scenario).teams]
    return teams[0] if teams else "red"


@pytest.fixture
def robo_match(tmp_path: Path, robo_scenario: Path) -> Iterator[Match]:
    """A real core process serving ``robo_scenario`` in practice mode (stopped at teardown)."""
    m = start_match(tmp_path / "state", robo_scenario)
    try:
        yield m
    finally:
        m.close()


@pytest.fixture
def robo_bench(robo_scenario: Path, robo_team: str) -> Iterator[Bench]:
    """A :class:`Bench` with one robot of ``robo_team`` on ``robo_scenario`` (seed 0)."""
    from robo_comp.engine.bench import Bench  # the engine loads numpy, numba and the sandbox: on first use

    b = Bench(robo_scenario, robo_team)
    try:
        yield b
    finally:
        b.close()

"""The pytest plugin of robo_comp: test team code against a real match or a seeded bench.

Installed with robo_comp (entry point ``pytest11``), so a team package's tests get these
fixtures without a ``conftest.py``:

``robo_scenario``
    Path of the scenario file the tests use: ``--robo-scenario`` on the command line, else the
    ``robo_comp_scenario`` ini option (a path relative to the rootdir, or the name of a bundled
    scenario such as ``demo_room``), else the bundled ``demo_room``.
``robo_team``
    The team the tests play for: ``--robo-team``, else the ``robo_comp_team`` ini option, else
    the scenario's first team.
``robo_match``
    A :class:`Match`: a **real core process** serving the scenario (practice mode: the match is
    running at once) in a temporary state folder. Start robot hosts with
    :meth:`Match.robots`, talk to it with :meth:`Match.client`; everything is stopped at
    teardown.
``robo_bench``
    A :class:`Bench` (:mod:`robo_comp.engine`, the match engine the league plays on): the team's
    modules in the **real sandbox** (:class:`~robo_comp.sandbox.parent.Sandbox`, a separate
    restricted process), the same match model and task runtime as a live match, on an in-process,
    seeded simulation of the scenario and a step-locked simulated clock. :meth:`Bench.run` runs one task,
    :meth:`Bench.run_match` a whole match (task lists for many robots, a simulated duration; a
    :class:`MatchRun` with the score, the finds and a JSON-lines event log). Deterministic: the
    same code, scenario and seed give the same event log.

Helpers: :func:`wait_for`, :func:`wait_robots`, :func:`next_event_where`; for the template's
explorer on the bench, :func:`sweep_plan` and :func:`report_seen`.

In a real match, upload a module with ``client.upload(tags, filename, source)`` and give its
tasks like any other; on the bench the same module runs without a core.
"""
from __future__ import annotations

from typing import Any

from robo_comp.testing.match import Match, next_event_where, start_match, wait_for, wait_robots
from robo_comp.world.scenario import DEFAULT_SCENARIO, resolve_scenario

#: The engine's names, imported when first used (the engine loads numpy, numba and the sandbox;
#: pytest loads this plugin in every run).
_ENGINE = ("Bench", "MatchRun", "TaskError", "report_seen", "sweep_plan")


def __getattr__(name: str) -> Any:
    if name in _ENGINE:
        import robo_comp.engine as engine

        return getattr(engine, name)
    raise AttributeError(f"module 'robo_comp.testing' has no attribute {name!r}")


__all__ = ["Bench", "DEFAULT_SCENARIO", "Match", "MatchRun", "TaskError", "next_event_where", "resolve_scenario",
           "report_seen", "start_match", "sweep_plan", "wait_for", "wait_robots"]

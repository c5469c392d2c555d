"""The engine: a whole match in one process, on a simulated clock, for tests, benches and leagues.

:class:`~robo_comp.engine.bench.Bench` drives the same match model as a live core
(:class:`robo_comp.match.model.Match`: task ids and states, the robots' lifecycle, the clock and
its phases, the find judge, the scoring rules) and runs the robots' tasks in the same task
runtime as a robot host (:class:`robo_comp.robots.runtime.TaskRuntime`: built-in tasks, uploaded
team code in the real sandbox, interrupts, the bump rule), in a seeded simulated arena. Nothing
depends on real time, so the same scenario, seed and code give the same event log.
"""
from robo_comp.engine.bench import (
    CALL_BURST, MOVEMENT_CALLS, PICTURE_CALLS, POSE_SAMPLE, Bench, Budget, Forfeit, MatchRun, TaskError,
)
from robo_comp.engine.plans import TaskStep, report_seen, sweep_plan

__all__ = ["Bench", "Budget", "CALL_BURST", "Forfeit", "MatchRun", "MOVEMENT_CALLS", "PICTURE_CALLS", "POSE_SAMPLE",
           "TaskError", "TaskStep", "report_seen", "sweep_plan"]

"""Every hook robo_comp calls, with who calls it, when, and what it may return.

Plugins implement these with ``@hookimpl`` and are registered through the ``robo_comp``
entry-point group (``[project.entry-points.robo_comp]``) or by calling
``get_plugin_manager().register(obj)``; never by import side effects. Team uploads do not
become host-side plugins: they run in the sandbox, and the host wraps their declared tasks
in a plugin of its own (see :mod:`robo_comp.sandbox.parent`).
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

import pluggy

if TYPE_CHECKING:  # types only, as pytest's hookspecs do: the hooks' callers import this module
    from robo_comp.robots.steps import CellPath, TaskSpec
    from robo_comp.scoring.config import ScoringConfig

PROJECT = "robo_comp"
hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)


class BoardView(Protocol):
    """What a scoring plugin sees of the scoreboard (a :class:`robo_comp.scoring.board.Scoreboard`)."""

    config: ScoringConfig
    #: victim id -> the team that found it first
    first_finder: dict[str, str]


class HostedRobot(Protocol):
    """A robot as a robot host's plugins see it (a :class:`robo_comp.robots.runtime.SimRobot`):
    what its tasks see (:class:`robo_comp.robots.steps.RobotView`) and its robot id."""

    tag: int
    robot_id: str

    def cell(self) -> tuple[int, int]:
        """The robot's current cell."""

    def plan_to(self, goal: tuple[int, int]) -> CellPath | None:
        """A path from the current cell to ``goal`` (inclusive), or None."""

    def in_bounds(self, x: int, y: int) -> bool:
        """True when ``(x, y)`` is a free cell of the arena."""


# ---------------------------------------------------------------------- tasks
@hookspec
def robo_comp_tasks() -> list[TaskSpec]:
    """Called by a robot host at start-up and whenever its plugins change, to collect the
    tasks its robots advertise.

    Return a list of :class:`robo_comp.robots.steps.TaskSpec`. When two plugins offer a task
    of the same name, the one registered *later* wins (a team's code upload replaces a
    built-in's behaviour this way).
    """


@hookspec
def robo_comp_task_interrupted(robot: HostedRobot, task_name: str, task_id: int, by_task_id: int) -> None:
    """Called by the robot host when a new task is given "now" while ``task_name`` runs on
    ``robot``; the switch itself happens at the next movement boundary. Return nothing."""


@hookspec
def robo_comp_tasks_offered(team: str, tag: int, tasks: list[dict[str, Any]],
                            teammates: list[dict[str, Any]]) -> list[dict[str, Any]] | None:
    """Called by the match (live in the core, and on the engine) when robot ``tag`` of ``team`` is
    lost or leaves with work left: ``tasks`` are its running, pending and queued tasks
    (``task_id``, ``name``, ``args``, ``state``), ``teammates`` the team's connected robots as the
    ``robots`` listing shows them (``tag``, ``x``, ``y``, ``task``, ``queue``, ...).

    Return ``[{"task_id": id, "tag": teammate}, ...]`` to move tasks to teammates of your
    choosing (each is cancelled on the lost robot and queued on the teammate), or None / ``[]``.
    The first plugin that names a task wins it; a teammate that does not advertise the task is
    passed over. Tasks no plugin moves go to the built-in reallocation when the team turned it on
    (``robo-comp ctl teamwork on``), else they wait for the lost robot. Must be fast and must not
    raise."""


# ---------------------------------------------------------------------- extensions
@hookspec
def robo_comp_extension_loaded(tag: int, name: str, version: str, sha256: str, tasks: list[str]) -> None:
    """Called by the robot host after an uploaded module passed the checked init contract and
    became active on robot ``tag``. Return nothing."""


@hookspec
def robo_comp_extension_unloaded(tag: int, name: str) -> None:
    """Called by the robot host after an extension was unloaded from robot ``tag``, or replaced
    there by a newer upload of the same name (before ``robo_comp_extension_loaded`` for the
    new one). Return nothing."""


# ---------------------------------------------------------------------- drivers and sensors
@hookspec(firstresult=True)
def robo_comp_driver(kind: str, options: dict[str, Any]) -> Any:
    """Called by the robot host once per robot to get the driver that moves it.

    ``kind`` names the driver (``"sim"``, ``"er1"``, ...). Return an object with
    ``begin(step)``, ``update(dt) -> bool``, ``halt()``, ``cell()``, ``moving`` and ``x, y,
    heading`` (see :class:`robo_comp.robots.drivers.ArenaDriver`), or None if ``kind`` is not yours.
    The first non-None answer is used.
    """


@hookspec
def robo_comp_sense(robot: HostedRobot) -> dict[str, Any]:
    """Called by the robot host when it reads robot ``robot``'s sensors (with its report, at the
    host's sensor rate); return sensor readings as plain data (merged into the report's
    ``sensors`` map), or an empty dict. A plugin that raises loses its own readings only."""


# ---------------------------------------------------------------------- scoring
@hookspec(firstresult=True)
def robo_comp_judge_find(find: dict[str, Any], truth: dict[str, Any]) -> dict[str, Any] | None:
    """Called by the scoreboard when a team reports a find. ``find`` is the report (team,
    tag, x, y, kind, evidence), ``truth`` what the arena knows (victims, what the robot
    examined, its sensor range). Return ``{"valid": bool, "victim": id or None, "reason": str}``.
    The first non-None answer is used."""


@hookspec
def robo_comp_score(event: dict[str, Any], board: BoardView) -> list[dict[str, Any]]:
    """Called by the scoreboard for every scoring-relevant event (``find.judged``,
    ``robot.bump``, ``robot.lost``, ``penalty``). Return a list of score changes
    ``{"team": str, "points": float, "reason": str, "kind": str}`` (possibly empty).
    All plugins' changes are applied."""


@hookspec(firstresult=True)
def robo_comp_rank(rows: list[dict[str, Any]]) -> list[dict[str, Any]] | None:
    """Called by the scoreboard to order teams; return the rows sorted best first with a
    ``rank`` key, or None to leave it to the next plugin. Document your tie-breaks."""


# ---------------------------------------------------------------------- events
@hookspec
def robo_comp_event(topic: str, team: str | None, data: dict[str, Any]) -> None:
    """Called by the core for every event it emits, except ``robot.positions`` (too frequent),
    after the event was logged. Must be fast and must not raise. Return nothing."""

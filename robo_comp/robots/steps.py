"""Movement steps and the task interface robots run.

A task is a generator function ``run(robot, *args)`` that yields :class:`Step` objects.
Each step is one movement (or a picture); the runtime completes it before asking the
generator for the next one, so an *interrupt* (a new task given "now") takes effect at a
movement boundary, while a *stop* halts in the middle of a step. The generator's return
value is the task's result; raising :class:`TaskFailed` ends it with a clear status.

What comes back for a :class:`Move` is None when the robot made it, or a :class:`Replan` when it
did not (a teammate holds the cell, an obstacle the map does not show is in the way) or when it
ended somewhere else (a positioning fix moved the robot off its path): the task then plans again
from where the robot is (``robo_comp.robots.builtin_tasks`` shows how).
"""
from __future__ import annotations

from collections.abc import Callable, Generator
from dataclasses import dataclass, field
from typing import Any, Protocol


@dataclass(frozen=True, slots=True)
class Move:
    """Drive to the neighbouring cell ``(x, y)`` (turning to face it first)."""

    x: int
    y: int


@dataclass(frozen=True, slots=True)
class Turn:
    """Turn on the spot by ``degrees`` (positive = clockwise on the map, y pointing down)."""

    degrees: float


@dataclass(frozen=True, slots=True)
class Capture:
    """Take a picture with the camera; it is uploaded with the task's result."""

    label: str = ""


@dataclass(frozen=True, slots=True)
class Wait:
    """Stand still for ``seconds``."""

    seconds: float


@dataclass(frozen=True, slots=True)
class Compute(Wait):
    """Team code computes (a sandboxed task between two robot calls, run ``run_id``): the robot
    stands still. A robot host looks again after ``seconds`` (a driver takes it as a
    :class:`Wait`); the engine waits for the team code at once, with its clock stopped (step-locked:
    team code computes in no simulated time, one robot at a time)."""

    run_id: int = 0


@dataclass(frozen=True, slots=True)
class Plan:
    """Plan a path from the robot's cell to ``goal``, off the host's loop: the robot stands at a
    movement boundary meanwhile, and the path (a list of cells, start and goal included, or None
    when there is none) comes back as the value of the ``yield``. ``avoid_robots``: around the
    cells the host's other robots stand in (straight through them when there is no way around)."""

    goal: tuple[int, int]
    avoid_robots: bool = True


@dataclass(frozen=True, slots=True)
class Record:
    """Start filming with the camera (``label``: the video's name), or, with ``label`` None, stop
    and upload the video; the robot goes on meanwhile (the runtime takes a frame every
    ``1 / robo_comp.world.video.FPS`` seconds). Takes no time itself. The video's id comes with
    the task's result (``videos``), as pictures' do."""

    label: str | None = None


@dataclass(frozen=True, slots=True)
class Replan:
    """What comes back for a :class:`Move` the robot did not make, or that did not end where it
    should: plan again from where the robot is. ``reason`` is ``"teammate"`` (a teammate held the
    cell longer than the runtime waits), ``"robot"`` (another host's or team's robot kept driving
    into it), ``"obstacle"`` (the robot's sensors saw the cell blocked,
    and it was reported for the team's map), ``"wall"`` (the cell is blocked on the map, as the
    team knows it now) or ``"off path"`` (the robot is not next to the cell, or a fix moved it
    elsewhere during the move); ``cell`` is the cell of the move."""

    reason: str
    cell: tuple[int, int] | None = None


Step = Move | Turn | Capture | Wait | Compute | Plan | Record

#: A planned path: cells from the robot's cell to the goal, both included.
CellPath = list[tuple[int, int]]
#: What the runtime sends back into a task for the step it yielded: the path (or None when
#: there is none) for a :class:`Plan`, None or a :class:`Replan` for a :class:`Move`, None for
#: every other step.
Answer = CellPath | Replan | None


class TaskFailed(Exception):
    """Raised by a task to end with ``ok = False`` and this message as its status.

    ``reason`` says why in one word (the task's result carries it: ``failed``, or for team code
    what the sandbox said: ``error``, ``limit``, ``cancelled``, ``restart``); ``line`` is the line
    of team code that raised, where known."""

    def __init__(self, message: str, reason: str = "failed", line: int | None = None,
                 traceback: list[str] | None = None, details: dict[str, Any] | None = None) -> None:
        super().__init__(message)
        self.reason = reason
        self.line = line
        #: Team code's traceback through its own files (``file:line in function: code``), where known.
        self.traceback = traceback or []
        #: More for the task's result (plain data), e.g. a ``goTo``'s ``end_error``.
        self.details = details or {}


class RobotView(Protocol):
    """What a task sees of its robot: plain data and planning, no host internals."""

    tag: int

    def cell(self) -> tuple[int, int]:
        """The robot's current cell."""

    def pose(self) -> tuple[float, float, float]:
        """Where the robot believes it is: ``(x, y, heading)`` (the positioning system's estimate)."""

    def plan_to(self, goal: tuple[int, int]) -> CellPath | None:
        """A path from the current cell to ``goal`` (inclusive), or None."""

    def in_bounds(self, x: int, y: int) -> bool:
        """True when ``(x, y)`` is a free cell of the arena."""


#: A task's generator: it yields steps, gets an :data:`Answer` back for each, and returns its
#: result (a dict for the built-in tasks, anything plain for team code's).
TaskRun = Generator[Step, Answer, Any]
TaskFn = Callable[..., TaskRun]


def no_steps() -> TaskRun:
    """A task run with no steps at all: it ends at once, and can be closed like any other."""
    return
    yield


@dataclass(slots=True)
class TaskSpec:
    """A task a robot can run: its advertised description and its generator function."""

    name: str
    run: TaskFn
    args: list[dict[str, str]] = field(default_factory=list)
    description: str = ""
    source: str = "builtin"

    def advert(self) -> dict[str, Any]:
        """The description sent to the core in ``register``."""
        return {"name": self.name, "description": self.description, "args": self.args}

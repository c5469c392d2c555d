"""The organiser's marker file: which marker is which robot, and which floor marker sits where.

A TOML file::

    marker_cm = 18            # side of the printed robot markers (for the record)
    [robots]                  # marker id = robot id (a host's robots are TEAM-1, TEAM-2, ... by default)
    10 = "red-1"
    11 = "red-2"
    20 = "blue-1"
    [floor]                   # floor marker id = the cell [x, y] its centre is on
    0 = [0, 0]
    1 = [23, 0]
    2 = [23, 19]
    3 = [0, 19]

Only the organiser writes it: a marker moves only the robot it is bound to, a robot has one
marker, and a robot host takes fixes for its own robots only, so a team cannot claim another
team's marker (or robot) by sticking a marker on its own robot.
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from robo_comp.errors import FieldError
from robo_comp.world.overhead.markers import check_id


@dataclass(frozen=True)
class Bindings:
    """Robot markers (id → robot id) and floor markers (id → cell)."""

    robots: dict[int, str] = field(default_factory=dict)
    floor: dict[int, tuple[float, float]] = field(default_factory=dict)
    marker_cm: float = 18.0

    def robot_of(self, marker: int) -> str | None:
        """The robot bound to ``marker`` (None: not a robot marker)."""
        return self.robots.get(marker)

    def to_toml(self) -> str:
        """The file form (what :func:`load_bindings` reads)."""
        lines = [f"marker_cm = {self.marker_cm:g}", "", "[robots]"]
        lines += [f'{m} = "{r}"' for m, r in sorted(self.robots.items())]
        lines += ["", "[floor]"]
        lines += [f"{m} = [{x:g}, {y:g}]" for m, (x, y) in sorted(self.floor.items())]
        return "\n".join(lines) + "\n"


def parse_bindings(data: dict[str, Any], source: str = "<markers>") -> Bindings:
    """Check a parsed marker file; :class:`FieldError` names the first thing wrong."""
    robots: dict[int, str] = {}
    seen: dict[str, int] = {}
    for key, robot in (data.get("robots") or {}).items():
        marker = _marker_key(key, source, "robots")
        if type(robot) is not str or not 0 < len(robot) <= 64:
            raise FieldError(f"{source}: [robots] {key} must name a robot id, e.g. \"red-1\"")
        if robot in seen:
            raise FieldError(f"{source}: robot {robot!r} is bound to markers {seen[robot]} and {marker}; "
                             "one marker per robot")
        seen[robot] = marker
        robots[marker] = robot
    floor: dict[int, tuple[float, float]] = {}
    for key, cell in (data.get("floor") or {}).items():
        marker = _marker_key(key, source, "floor")
        if marker in robots:
            raise FieldError(f"{source}: marker {marker} is both a robot's and a floor marker")
        if (type(cell) is not list or len(cell) != 2
                or not all(type(c) in (int, float) for c in cell)):
            raise FieldError(f"{source}: [floor] {key} must be the cell [x, y] of the marker's centre")
        floor[marker] = (float(cell[0]), float(cell[1]))
    size = data.get("marker_cm", 18.0)
    if type(size) not in (int, float) or not 1 <= size <= 200:
        raise FieldError(f"{source}: marker_cm must be the printed side in cm (1..200)")
    return Bindings(robots, floor, float(size))


def _marker_key(key: str, source: str, table: str) -> int:
    try:
        return check_id(int(key))
    except (ValueError, FieldError):
        raise FieldError(f"{source}: [{table}] keys are marker ids 0..249, not {key!r}") from None


def load_bindings(path: str | Path) -> Bindings:
    """Read and check a marker file (:class:`FieldError` with the file's name if it is wrong)."""
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text())
    except OSError as e:
        raise FieldError(f"cannot read the marker file {p}: {e.strerror}") from None
    except tomllib.TOMLDecodeError as e:
        raise FieldError(f"{p}: not valid TOML ({e})") from None
    return parse_bindings(data, str(p))

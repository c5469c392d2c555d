"""Scenario files: the arena, victims, teams and simulation settings of one match.

A scenario is a TOML file (read with :mod:`tomllib`) described in ``docs/scenarios.md``.
:func:`load_scenario` reads one from disk, :func:`parse_scenario` from text, and
:func:`default_scenario` returns the built-in arena the core uses when none is given.
Every problem in a file -- syntax, unknown keys, wrong types, values out of range,
victims inside walls, overlapping start zones, missing map files -- raises
:class:`robo_comp.errors.ScenarioError` whose message names the file, the line and the
field, e.g. ``demo.toml line 14: victims[2].x = 40 is outside the 24×16 map``.

Coordinates are map cells: ``x`` is the column, ``y`` the row (row 0 at the top), and
``walls[y, x]`` is True where a cell is blocked. A robot standing "in cell (x, y)" has
its centre at the point ``(x, y)``.
"""
from __future__ import annotations

import difflib
import math
import os
import re
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

import numpy as np

from robo_comp.errors import ScenarioError

if TYPE_CHECKING:  # for the annotation only; :attr:`Scenario.grid` imports it when used
    from robo_comp.world.maps import GridMap

__all__ = [
    "MAX_SIDE", "Rect", "Zone", "KnownObject", "Victim", "Team", "CostConfig",
    "Positioning", "Drift", "Kinematics", "SensorConfig", "CameraConfig", "Scenario",
    "load_scenario", "parse_scenario", "default_scenario", "bundled_scenarios",
    "bundled_scenario_path",
]

#: Largest accepted map side in cells (and the largest accepted map is MAX_SIDE²).
MAX_SIDE = 10_000
_MAX_ROBOTS_PER_TEAM = 10_000
_MAX_TEAMS = 64
_MAX_ITEMS = 100_000
_MAX_DURATION = 7 * 24 * 3600

_COLOURS = {
    "red": "#d03030", "blue": "#3060d0", "green": "#30a040", "yellow": "#e0c020",
    "orange": "#e08020", "purple": "#8040b0", "cyan": "#20b0c0", "magenta": "#c030a0",
    "white": "#f0f0f0", "black": "#202020", "grey": "#808080", "gray": "#808080",
}

#: Zone kinds that the downward range sensor sees as a drop (an edge or stairs).
DROP_KINDS = frozenset({"stairs", "drop", "hole", "edge"})


# --------------------------------------------------------------------------- records


@dataclass(frozen=True)
class Rect:
    """An axis-aligned rectangle of cells: columns ``x .. x+w-1``, rows ``y .. y+h-1``."""

    x: int
    y: int
    w: int
    h: int

    def contains(self, x: float, y: float) -> bool:
        """True if the cell holding point (x, y) lies in the rectangle."""
        cx, cy = math.floor(x + 0.5), math.floor(y + 0.5)
        return self.x <= cx < self.x + self.w and self.y <= cy < self.y + self.h

    def overlaps(self, other: "Rect") -> bool:
        """True if the two rectangles share at least one cell."""
        return (self.x < other.x + other.w and other.x < self.x + self.w
                and self.y < other.y + other.h and other.y < self.y + self.h)

    def cells(self) -> list[tuple[int, int]]:
        """All cells of the rectangle, row by row."""
        return [(x, y) for y in range(self.y, self.y + self.h) for x in range(self.x, self.x + self.w)]

    def to_dict(self) -> dict[str, int]:
        """Plain-data form ``{"x", "y", "w", "h"}``."""
        return {"x": self.x, "y": self.y, "w": self.w, "h": self.h}


@dataclass(frozen=True)
class Zone:
    """A surface zone (rubble, water, stairs, ...) that slows robots and may be dangerous.

    ``speed_factor`` multiplies robot speed inside the zone (0 < f <= 1 slows, 0 would
    stop, so it must be > 0); ``danger`` is a 0..1 rating scoring may use; ``cost`` is a
    path cost for planners (cells take ``max(cost, obstacle cost)``); ``drop`` marks an
    edge that the downward sensor sees (default True for stairs/drop/hole/edge).
    """

    kind: str
    rect: Rect
    speed_factor: float = 1.0
    danger: float = 0.0
    cost: float = 1.0
    drop: bool = False
    name: str = ""

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form of the zone."""
        return {"kind": self.kind, "name": self.name, **self.rect.to_dict(),
                "speed_factor": self.speed_factor, "danger": self.danger,
                "cost": self.cost, "drop": self.drop}


@dataclass(frozen=True)
class KnownObject:
    """An object every team knows about from the start (a table, a door, a landmark)."""

    id: str
    kind: str
    x: int
    y: int
    description: str = ""

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form of the object."""
        return {"id": self.id, "kind": self.kind, "x": self.x, "y": self.y,
                "description": self.description}


@dataclass(frozen=True)
class Victim:
    """A hidden victim: ground truth only the arena and the referee know."""

    id: str
    x: int
    y: int
    kind: str = "adult"
    points: int | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form of the victim."""
        return {"id": self.id, "x": self.x, "y": self.y, "kind": self.kind, "points": self.points}


@dataclass(frozen=True)
class Team:
    """A team: name, display colour (``#rrggbb``), start zone and number of robots."""

    name: str
    colour: str
    start: Rect
    robots: int = 1

    @property
    def rgb(self) -> tuple[int, int, int]:
        """The colour as an (r, g, b) tuple of 0..255."""
        c = self.colour.lstrip("#")
        return int(c[0:2], 16), int(c[2:4], 16), int(c[4:6], 16)

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form of the team."""
        return {"name": self.name, "colour": self.colour, "start": self.start.to_dict(),
                "robots": self.robots}


@dataclass(frozen=True)
class CostConfig:
    """Cell costs (thesis appendix A): ``normal`` is 1, cells within ``radius`` of a wall cost ``near_cost``."""

    normal: float = 1.0
    near_cost: float = 10.0
    radius: int = 1


@dataclass(frozen=True)
class Positioning:
    """The simulated tracking positioning system (Hexamite HX5 style).

    ``rate`` fixes per second per robot, ``noise`` the σ of the Gaussian position error in
    cells, ``dropout`` the probability that a due fix is lost.
    """

    rate: float = 2.0
    noise: float = 0.25
    dropout: float = 0.05


@dataclass(frozen=True)
class Drift:
    """Dead-reckoning error: ``distance`` is the σ of the relative distance error
    (0.02 = 2 % of each move), ``heading`` the σ in degrees per 90° turned, and
    ``heading_per_cell`` the σ in degrees of heading wander per cell driven."""

    distance: float = 0.02
    heading: float = 1.0
    heading_per_cell: float = 0.2


@dataclass(frozen=True)
class Kinematics:
    """Robot motion: ``speed`` in cells/s, ``turn_rate`` in deg/s, ``drive`` ``"grid4"`` or ``"free"``."""

    speed: float = 2.0
    turn_rate: float = 90.0
    drive: str = "grid4"


@dataclass(frozen=True)
class SensorConfig:
    """Ultrasonic range sensors as in thesis appendix B (SRF04: about 10..300 cm).

    ``min_range``/``max_range`` in cm, ``noise`` σ in cm, ``floor`` the down sensor's
    normal reading in cm and ``drop_depth`` what is added over a drop (the thesis robot
    treated > 35 cm as an edge).
    """

    min_range: float = 10.0
    max_range: float = 300.0
    noise: float = 1.0
    floor: float = 20.0
    drop_depth: float = 60.0


@dataclass(frozen=True)
class CameraConfig:
    """The robot camera: field of view in degrees and range in cells."""

    fov: float = 90.0
    range: float = 6.0


@dataclass
class Scenario:
    """One match set-up; ``walls`` already includes the walls added by the file."""

    name: str
    source: str
    walls: np.ndarray
    cell_size: float = 25.0
    costs: CostConfig = field(default_factory=CostConfig)
    zones: list[Zone] = field(default_factory=list)
    objects: list[KnownObject] = field(default_factory=list)
    victims: list[Victim] = field(default_factory=list)
    teams: list[Team] = field(default_factory=list)
    duration: float = 600.0
    seed: int = 0
    positioning: Positioning = field(default_factory=Positioning)
    drift: Drift = field(default_factory=Drift)
    kinematics: Kinematics = field(default_factory=Kinematics)
    sensors: SensorConfig = field(default_factory=SensorConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    shared_discoveries: bool = False
    map_name: str = ""
    #: The ``[scoring]`` table as given (validated): overrides of the default rules' points.
    scoring: dict[str, Any] = field(default_factory=dict)
    #: ``[match] approve_uploads``: a team's upload during a running match waits for the referee.
    approve_uploads: bool = False
    #: ``[[debris]]``: blocked cells that are not on the map (rubble fallen since it was drawn):
    #: ground truth like the victims, in the simulated arena only; robots find them with their
    #: sensors and report them for their team's map.
    debris: list[Rect] = field(default_factory=list)

    def debris_mask(self) -> np.ndarray:
        """The ``[[debris]]`` cells as a bool grid ``[y, x]`` (the map's walls left out)."""
        mask = np.zeros(self.walls.shape, dtype=bool)
        for r in self.debris:
            mask[r.y:r.y + r.h, r.x:r.x + r.w] = True
        return mask & ~self.walls

    @property
    def width(self) -> int:
        """Map width in cells."""
        return int(self.walls.shape[1])

    @property
    def height(self) -> int:
        """Map height in cells."""
        return int(self.walls.shape[0])

    @property
    def grid(self) -> GridMap:
        """The map (with the added walls) as a :class:`robo_comp.world.maps.GridMap`."""
        from robo_comp.world.maps import GridMap

        return GridMap(walls=self.walls, name=self.map_name or self.name)

    def team(self, name: str) -> Team:
        """The team called ``name`` (KeyError if there is none)."""
        for t in self.teams:
            if t.name == name:
                return t
        raise KeyError(name)

    def cost_grid(self) -> np.ndarray:
        """Cell costs (h, w), all >= 1: normal cost, ``near_cost`` near walls, zone costs
        (see :func:`compute_costs`); pass it as ``costs=`` to ``planner.find_path``."""
        return compute_costs(self.walls, self.costs, self.zones)

    def start_cells(self, team: str) -> list[tuple[int, int]]:
        """The free cells of ``team``'s start zone, row by row."""
        r = self.team(team).start
        return [(x, y) for (x, y) in r.cells() if not self.walls[y, x]]


def compute_costs(walls: np.ndarray, cfg: CostConfig, zones: list[Zone] | tuple = ()) -> np.ndarray:
    """Cost grid (float64, >= 1) for ``walls`` following thesis appendix A, in the
    convention of :func:`robo_comp.world.planner.obstacle_costs` (wall cells hold the
    normal cost; the planner never enters them), so it can go straight to ``find_path``.
    Zone costs raise cells to ``max(cost, zone.cost)``."""
    from robo_comp.world.planner import obstacle_costs

    costs = obstacle_costs(walls, near_cost=max(cfg.near_cost, cfg.normal), radius=int(cfg.radius))
    if cfg.normal != 1.0:
        costs[costs == 1.0] = cfg.normal
    for z in zones:
        if z.cost != 1.0:
            sl = (slice(z.rect.y, z.rect.y + z.rect.h), slice(z.rect.x, z.rect.x + z.rect.w))
            costs[sl] = np.maximum(costs[sl], z.cost)
    return costs


# ------------------------------------------------------------------- line locating


class _KeyLines:
    """Finds the line of a key path such as ``("victims", 2, "x")`` in TOML text."""

    _table = re.compile(r"^\s*\[\s*([^\[\]]+?)\s*\]\s*(#.*)?$")
    _array = re.compile(r"^\s*\[\[\s*([^\[\]]+?)\s*\]\]\s*(#.*)?$")
    _key = re.compile(r"^\s*([A-Za-z0-9_\-\.\"' ]+?)\s*=")
    _inline_key = re.compile(r"([A-Za-z0-9_\-]+)\s*=")

    def __init__(self, text: str) -> None:
        self.lines: dict[tuple, int] = {}
        counts: dict[tuple, int] = {}
        current: tuple = ()
        in_string: str | None = None
        for no, line in enumerate(text.splitlines(), start=1):
            if in_string:
                if line.count(in_string) % 2 == 1:
                    in_string = None
                continue
            m = self._array.match(line)
            if m:
                base = self._split(m.group(1))
                idx = counts.get(base, 0)
                counts[base] = idx + 1
                current = base + (idx,)
                self.lines.setdefault(base, no)
                self.lines[current] = no
                continue
            m = self._table.match(line)
            if m:
                current = self._split(m.group(1))
                self.lines.setdefault(current, no)
                continue
            m = self._key.match(line)
            if m:
                path = current + self._split(m.group(1))
                self.lines.setdefault(path, no)
                rest = line[m.end():]
                if rest.lstrip().startswith("{"):
                    for km in self._inline_key.finditer(rest):
                        self.lines.setdefault(path + (km.group(1),), no)
                for q in ('"""', "'''"):
                    if rest.count(q) % 2 == 1:
                        in_string = q
                        break

    @staticmethod
    def _split(dotted: str) -> tuple:
        return tuple(p.strip().strip("\"'") for p in dotted.split("."))

    def find(self, path: tuple) -> int | None:
        """The line of ``path`` or of its nearest ancestor that is in the text."""
        p = tuple(path)
        while p:
            if p in self.lines:
                return self.lines[p]
            p = p[:-1]
        return None


def _path_str(path: tuple) -> str:
    out = ""
    for p in path:
        if isinstance(p, int):
            out += f"[{p}]"
        else:
            out += ("." if out else "") + str(p)
    return out or "(top level)"


class _Ctx:
    """Validation context: raises ScenarioError naming the file, line and field."""

    def __init__(self, text: str, source: str) -> None:
        self.source = source
        self.keys = _KeyLines(text)

    def fail(self, path: tuple, message: str) -> NoReturn:
        line = self.keys.find(path)
        where = f"{self.source} line {line}" if line else self.source
        raise ScenarioError(f"{where}: {_path_str(path)} {message}", file=self.source,
                            line=line, field=_path_str(path))

    # -- typed getters -------------------------------------------------------------

    def table(self, data: dict, key: str, path: tuple, allowed: set[str]) -> dict:
        value = data.get(key, {})
        if not isinstance(value, dict):
            self.fail(path + (key,), f"must be a table, not {_tname(value)}")
        self.check_keys(value, allowed, path + (key,))
        return value

    def check_keys(self, data: dict, allowed: set[str], path: tuple) -> None:
        for k in data:
            if k not in allowed:
                near = difflib.get_close_matches(k, sorted(allowed), n=1)
                hint = f" (did you mean {near[0]!r}?)" if near else ""
                where = _path_str(path + (k,))
                line = self.keys.find(path + (k,))
                loc = f"{self.source} line {line}" if line else self.source
                raise ScenarioError(f"{loc}: unknown key {where}{hint}", file=self.source,
                                    line=line, field=where)

    def num(self, data: dict, key: str, path: tuple, default: float | None = None, *,
            lo: float | None = None, hi: float | None = None, lo_open: bool = False,
            integer: bool = False) -> Any:
        p = path + (key,)
        if key not in data:
            if default is None:
                self.fail(p, "is required")
            return default
        v = data[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self.fail(p, f"must be a number, not {_tname(v)}")
        if integer and not isinstance(v, int):
            if isinstance(v, float) and v.is_integer() and abs(v) < 2 ** 53:
                v = int(v)
            else:
                self.fail(p, f"= {v!r} must be a whole number")
        if isinstance(v, float) and not math.isfinite(v):
            self.fail(p, f"= {v!r} must be a finite number")
        if lo is not None and (v <= lo if lo_open else v < lo):
            self.fail(p, f"= {v!r} must be {'>' if lo_open else '>='} {lo:g}")
        if hi is not None and v > hi:
            self.fail(p, f"= {v!r} must be <= {hi:g}")
        return v

    def string(self, data: dict, key: str, path: tuple, default: str | None = None, *,
               choices: tuple[str, ...] | None = None, max_len: int = 200) -> str:
        p = path + (key,)
        if key not in data:
            if default is None:
                self.fail(p, "is required")
            return default
        v = data[key]
        if not isinstance(v, str):
            self.fail(p, f"must be a string, not {_tname(v)}")
        if len(v) > max_len:
            self.fail(p, f"is too long ({len(v)} characters, at most {max_len})")
        if choices is not None and v not in choices:
            near = difflib.get_close_matches(v, choices, n=1)
            hint = f" (did you mean {near[0]!r}?)" if near else ""
            self.fail(p, f"= {v!r} must be one of {', '.join(map(repr, choices))}{hint}")
        return v

    def boolean(self, data: dict, key: str, path: tuple, default: bool) -> bool:
        if key not in data:
            return default
        v = data[key]
        if not isinstance(v, bool):
            self.fail(path + (key,), f"must be true or false, not {_tname(v)}")
        return v

    def array(self, data: dict, key: str, path: tuple) -> list[dict]:
        v = data.get(key, [])
        if not isinstance(v, list):
            self.fail(path + (key,), f"must be an array of tables ([[{key}]]), not {_tname(v)}")
        if len(v) > _MAX_ITEMS:
            self.fail(path + (key,), f"has {len(v)} entries, at most {_MAX_ITEMS}")
        for i, item in enumerate(v):
            if not isinstance(item, dict):
                self.fail(path + (key, i), f"must be a table, not {_tname(item)}")
        return v


def _tname(v: Any) -> str:
    return {bool: "a boolean", int: "an integer", float: "a float", str: "a string",
            list: "an array", dict: "a table"}.get(type(v), type(v).__name__)


# -------------------------------------------------------------------------- parsing

_TOP_KEYS = {"name", "map", "cell_size", "duration", "seed", "shared_discoveries", "walls", "debris",
             "costs", "zones", "objects", "victims", "teams", "positioning", "drift", "robot",
             "sensors", "camera", "scoring", "match"}
_SCORING_NUMS = ("default_points", "first_bonus", "false_report", "collision", "robot_lost", "match_radius")


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate the scenario file at ``path`` (TOML, see docs/scenarios.md)."""
    p = Path(path)
    try:
        if p.stat().st_size > 64 * 1024 * 1024:
            raise ScenarioError(f"{p}: scenario file is larger than 64 MB", file=str(p))
        text = p.read_bytes().decode("utf-8")
    except ScenarioError:
        raise
    except UnicodeDecodeError as e:
        raise ScenarioError(f"{p}: not UTF-8 text ({e.reason} at byte {e.start})", file=str(p)) from None
    except OSError as e:
        raise ScenarioError(f"{p}: cannot read scenario file: {e.strerror or e}", file=str(p)) from None
    return parse_scenario(text, str(p), base_dir=p.parent)


def parse_scenario(text: str, source: str = "<scenario>", *, base_dir: str | Path | None = None) -> Scenario:
    """Parse and validate scenario TOML ``text``; ``source`` names it in error messages and
    ``base_dir`` (default: the directory of ``source``) resolves a relative map path."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        msg = str(e)
        m = re.search(r"\(at line (\d+), column (\d+)\)", msg)
        if m:
            core = msg[: m.start()].strip()
            raise ScenarioError(f"{source} line {m.group(1)}: TOML syntax error: {core} "
                                f"(column {m.group(2)})", file=source, line=int(m.group(1))) from None
        if "end of document" in msg:
            last = max(1, len(text.splitlines()))
            raise ScenarioError(f"{source} line {last}: TOML syntax error: {msg}", file=source,
                                line=last) from None
        raise ScenarioError(f"{source}: TOML syntax error: {msg}", file=source) from None
    except RecursionError:
        raise ScenarioError(f"{source}: TOML nested too deeply", file=source) from None
    ctx = _Ctx(text, source)
    base = Path(base_dir) if base_dir is not None else Path(source).parent
    try:
        return _build(data, ctx, base)
    except ScenarioError:
        raise
    except (ValueError, TypeError, OverflowError, MemoryError, RecursionError) as e:  # pragma: no cover
        raise ScenarioError(f"{source}: invalid scenario: {e}", file=source) from None


def _build(data: dict, ctx: _Ctx, base: Path) -> Scenario:
    ctx.check_keys(data, _TOP_KEYS, ())
    name = ctx.string(data, "name", (), Path(ctx.source).stem or "scenario")
    cell_size = float(ctx.num(data, "cell_size", (), 25.0, lo=0, lo_open=True, hi=10_000))
    duration = float(ctx.num(data, "duration", (), 600.0, lo=0, lo_open=True, hi=_MAX_DURATION))
    seed = ctx.num(data, "seed", (), 0, lo=0, hi=2 ** 63 - 1, integer=True)
    shared = ctx.boolean(data, "shared_discoveries", (), False)

    walls, map_name = _load_map_field(data, ctx, base)
    h, w = walls.shape
    size = f"{w}×{h}"

    def cell(item: dict, path: tuple, xkey: str = "x", ykey: str = "y") -> tuple[int, int]:
        x = ctx.num(item, xkey, path, integer=True)
        y = ctx.num(item, ykey, path, integer=True)
        if not 0 <= x < w:
            ctx.fail(path + (xkey,), f"= {x} is outside the {size} map")
        if not 0 <= y < h:
            ctx.fail(path + (ykey,), f"= {y} is outside the {size} map")
        return x, y

    def rect(item: dict, path: tuple) -> Rect:
        x, y = cell(item, path)
        rw = ctx.num(item, "w", path, 1, lo=1, integer=True)
        rh = ctx.num(item, "h", path, 1, lo=1, integer=True)
        if x + rw > w:
            ctx.fail(path + ("w",), f"= {rw}: the rectangle from x = {x} runs outside the {size} map")
        if y + rh > h:
            ctx.fail(path + ("h",), f"= {rh}: the rectangle from y = {y} runs outside the {size} map")
        return Rect(x, y, rw, rh)

    # Walls added on top of the map.
    for i, item in enumerate(ctx.array(data, "walls", ())):
        path = ("walls", i)
        ctx.check_keys(item, {"x", "y", "w", "h"}, path)
        r = rect(item, path)
        walls[r.y:r.y + r.h, r.x:r.x + r.w] = True
    debris = []
    for i, item in enumerate(ctx.array(data, "debris", ())):
        path = ("debris", i)
        ctx.check_keys(item, {"x", "y", "w", "h"}, path)
        debris.append(rect(item, path))

    c = ctx.table(data, "costs", (), {"normal", "near_cost", "radius"})
    normal = float(ctx.num(c, "normal", ("costs",), 1.0, lo=1, hi=1e6))
    costs = CostConfig(
        normal=normal,
        near_cost=float(ctx.num(c, "near_cost", ("costs",), 10.0, lo=1, hi=1e6)),
        radius=ctx.num(c, "radius", ("costs",), 1, lo=0, hi=100, integer=True),
    )

    zones: list[Zone] = []
    for i, item in enumerate(ctx.array(data, "zones", ())):
        path = ("zones", i)
        ctx.check_keys(item, {"kind", "name", "x", "y", "w", "h", "speed_factor", "danger",
                              "cost", "drop"}, path)
        kind = ctx.string(item, "kind", path, max_len=40)
        zones.append(Zone(
            kind=kind, rect=rect(item, path),
            speed_factor=float(ctx.num(item, "speed_factor", path, 1.0, lo=0, lo_open=True, hi=10)),
            danger=float(ctx.num(item, "danger", path, 0.0, lo=0, hi=1)),
            cost=float(ctx.num(item, "cost", path, 1.0, lo=1, hi=1e6)),
            drop=ctx.boolean(item, "drop", path, kind in DROP_KINDS),
            name=ctx.string(item, "name", path, ""),
        ))

    objects: list[KnownObject] = []
    seen: set[str] = set()
    for i, item in enumerate(ctx.array(data, "objects", ())):
        path = ("objects", i)
        ctx.check_keys(item, {"id", "kind", "x", "y", "description"}, path)
        oid = ctx.string(item, "id", path, f"object-{i + 1}", max_len=80)
        if oid in seen:
            ctx.fail(path + ("id",), f"= {oid!r} is used twice")
        seen.add(oid)
        x, y = cell(item, path)
        objects.append(KnownObject(oid, ctx.string(item, "kind", path, "object", max_len=40), x, y,
                                   ctx.string(item, "description", path, "", max_len=2000)))

    victims: list[Victim] = []
    seen = set()
    for i, item in enumerate(ctx.array(data, "victims", ())):
        path = ("victims", i)
        ctx.check_keys(item, {"id", "x", "y", "kind", "points"}, path)
        vid = ctx.string(item, "id", path, f"victim-{i + 1}", max_len=80)
        if vid in seen:
            ctx.fail(path + ("id",), f"= {vid!r} is used twice")
        seen.add(vid)
        x, y = cell(item, path)
        if walls[y, x]:
            ctx.fail(path, f"at ({x}, {y}) is inside a wall")
        if any(d.contains(x, y) for d in debris):
            ctx.fail(path, f"at ({x}, {y}) is under debris")
        pts = item.get("points")
        if pts is not None:
            pts = ctx.num(item, "points", path, lo=-1_000_000, hi=1_000_000, integer=True)
        victims.append(Victim(vid, x, y, ctx.string(item, "kind", path, "adult", max_len=40), pts))

    teams: list[Team] = []
    team_items = ctx.array(data, "teams", ())
    if len(team_items) > _MAX_TEAMS:
        ctx.fail(("teams",), f"has {len(team_items)} teams, at most {_MAX_TEAMS}")
    for i, item in enumerate(team_items):
        path = ("teams", i)
        ctx.check_keys(item, {"name", "colour", "color", "start", "robots"}, path)
        tname = ctx.string(item, "name", path, max_len=40)
        if not tname.strip():
            ctx.fail(path + ("name",), "must not be empty")
        if any(t.name == tname for t in teams):
            ctx.fail(path + ("name",), f"= {tname!r} is used by two teams")
        ckey = "colour" if "colour" in item else "color"
        colour = ctx.string(item, ckey, path, _default_colour(i), max_len=20)
        colour = _COLOURS.get(colour.lower(), colour)
        if not re.fullmatch(r"#[0-9a-fA-F]{6}", colour):
            ctx.fail(path + (ckey,), f"= {colour!r} must be '#rrggbb' or one of {', '.join(sorted(_COLOURS))}")
        start_item = item.get("start")
        if not isinstance(start_item, dict):
            ctx.fail(path + ("start",), "must be a table {x, y, w, h}" if start_item is not None
                     else "is required (a start zone {x, y, w, h})")
        ctx.check_keys(start_item, {"x", "y", "w", "h"}, path + ("start",))
        start = rect(start_item, path + ("start",))
        robots = ctx.num(item, "robots", path, 1, lo=0, hi=_MAX_ROBOTS_PER_TEAM, integer=True)
        free = int((~walls[start.y:start.y + start.h, start.x:start.x + start.w]).sum())
        if robots > free:
            ctx.fail(path + ("robots",), f"= {robots} robots do not fit the {free} free cells of the start zone")
        for other in teams:
            if other.start.overlaps(start):
                ctx.fail(path + ("start",), f"overlaps the start zone of team {other.name!r}")
        teams.append(Team(tname, colour.lower(), start, robots))

    pos = ctx.table(data, "positioning", (), {"rate", "noise", "dropout"})
    positioning = Positioning(
        rate=float(ctx.num(pos, "rate", ("positioning",), 2.0, lo=0, lo_open=True, hi=1000)),
        noise=float(ctx.num(pos, "noise", ("positioning",), 0.25, lo=0, hi=1000)),
        dropout=float(ctx.num(pos, "dropout", ("positioning",), 0.05, lo=0, hi=1)),
    )
    d = ctx.table(data, "drift", (), {"distance", "heading", "heading_per_cell"})
    drift = Drift(
        distance=float(ctx.num(d, "distance", ("drift",), 0.02, lo=0, hi=1)),
        heading=float(ctx.num(d, "heading", ("drift",), 1.0, lo=0, hi=90)),
        heading_per_cell=float(ctx.num(d, "heading_per_cell", ("drift",), 0.2, lo=0, hi=90)),
    )
    k = ctx.table(data, "robot", (), {"speed", "turn_rate", "drive"})
    kin = Kinematics(
        speed=float(ctx.num(k, "speed", ("robot",), 2.0, lo=0, lo_open=True, hi=1000)),
        turn_rate=float(ctx.num(k, "turn_rate", ("robot",), 90.0, lo=0, lo_open=True, hi=36000)),
        drive=ctx.string(k, "drive", ("robot",), "grid4", choices=("grid4", "free")),
    )
    s = ctx.table(data, "sensors", (), {"min_range", "max_range", "noise", "floor", "drop_depth"})
    smin = float(ctx.num(s, "min_range", ("sensors",), 10.0, lo=0, hi=100_000))
    smax = float(ctx.num(s, "max_range", ("sensors",), 300.0, lo=0, lo_open=True, hi=100_000))
    if smax <= smin:
        ctx.fail(("sensors", "max_range"), f"= {smax:g} must be greater than min_range = {smin:g}")
    if smax / cell_size > 1000:
        ctx.fail(("sensors", "max_range"), f"= {smax:g} cm is more than 1000 cells of {cell_size:g} cm")
    sensors = SensorConfig(
        min_range=smin, max_range=smax,
        noise=float(ctx.num(s, "noise", ("sensors",), 1.0, lo=0, hi=10_000)),
        floor=float(ctx.num(s, "floor", ("sensors",), 20.0, lo=0, hi=10_000)),
        drop_depth=float(ctx.num(s, "drop_depth", ("sensors",), 60.0, lo=0, hi=100_000)),
    )
    cam = ctx.table(data, "camera", (), {"fov", "range"})
    camera = CameraConfig(
        fov=float(ctx.num(cam, "fov", ("camera",), 90.0, lo=1, hi=360)),
        range=float(ctx.num(cam, "range", ("camera",), 6.0, lo=0, lo_open=True, hi=1000)),
    )
    sc = ctx.table(data, "scoring", (), {"victim_points", *_SCORING_NUMS})
    scoring: dict[str, Any] = {}
    for key in _SCORING_NUMS:
        if key in sc:
            lo = 0.0 if key == "match_radius" else -1_000_000.0
            scoring[key] = float(ctx.num(sc, key, ("scoring",), lo=lo, hi=1_000_000))
    if "victim_points" in sc:
        vp = ctx.table(sc, "victim_points", ("scoring",), set(sc["victim_points"]) if isinstance(
            sc["victim_points"], dict) else set())
        scoring["victim_points"] = {k: float(ctx.num(vp, k, ("scoring", "victim_points"), lo=-1_000_000,
                                                     hi=1_000_000)) for k in vp}
    mt = ctx.table(data, "match", (), {"approve_uploads"})
    approve = ctx.boolean(mt, "approve_uploads", ("match",), False)
    return Scenario(name=name, source=ctx.source, walls=walls, cell_size=cell_size, costs=costs,
                    zones=zones, objects=objects, victims=victims, teams=teams,
                    duration=duration, seed=seed, positioning=positioning, drift=drift,
                    kinematics=kin, sensors=sensors, camera=camera,
                    shared_discoveries=shared, map_name=map_name, scoring=scoring,
                    approve_uploads=approve, debris=debris)


def _default_colour(i: int) -> str:
    return ["#d03030", "#3060d0", "#30a040", "#e0c020", "#8040b0", "#20b0c0"][i % 6]


def _load_map_field(data: dict, ctx: _Ctx, base: Path) -> tuple[np.ndarray, str]:
    """The wall grid of the ``map`` key: a path, an inline grid, or ``{width, height}``."""
    if "map" not in data:
        ctx.fail(("map",), "is required (a map file path, an inline grid, or {width, height})")
    m = data["map"]
    if isinstance(m, dict):
        ctx.check_keys(m, {"width", "height", "border"}, ("map",))
        w = ctx.num(m, "width", ("map",), lo=1, hi=MAX_SIDE, integer=True)
        h = ctx.num(m, "height", ("map",), lo=1, hi=MAX_SIDE, integer=True)
        walls = np.zeros((h, w), dtype=bool)
        if ctx.boolean(m, "border", ("map",), True):
            walls[0, :] = walls[-1, :] = True
            walls[:, 0] = walls[:, -1] = True
        return walls, f"empty {w}×{h}"
    if not isinstance(m, str):
        ctx.fail(("map",), f"must be a path, an inline grid or a table, not {_tname(m)}")
    from robo_comp.world import maps  # imported lazily: maps.py is owned by another module

    line = ctx.keys.find(("map",)) or 0
    inline = "\n" in m.strip("\n") or (m.strip() != "" and set(m.strip()) <= {".", "#"})
    try:
        if inline:
            grid = maps.parse_text_grid(m, ctx.source)
            name = "inline"
        else:
            p = Path(m)
            p = p if p.is_absolute() else base / p
            if not p.is_file():
                ctx.fail(("map",), f"= {m!r}: map file {str(p)!r} not found (or not a regular file)")
            if p.stat().st_size > (MAX_SIDE + 2) * MAX_SIDE + 4096:
                ctx.fail(("map",), f"= {m!r}: map file is too large")
            grid = maps.load_map(p)
            name = getattr(grid, "name", p.stem)
    except ScenarioError as e:
        if e.details.get("field") == ("map"):
            raise
        msg = e.message
        if inline:
            # parse_text_grid counts lines from the start of the grid; the grid text starts
            # on the line after ``map = """``.
            mm = re.match(re.escape(ctx.source) + r" line (\d+): (.*)", msg, re.S)
            if mm:
                fl = line + int(mm.group(1))
                raise ScenarioError(f"{ctx.source} line {fl}: map: {mm.group(2)}", file=ctx.source,
                                    line=fl, field="map") from None
            msg = msg.removeprefix(ctx.source + ": ")
            raise ScenarioError(f"{ctx.source} line {line}: map: {msg}", file=ctx.source,
                                line=line, field="map") from None
        raise ScenarioError(f"{ctx.source} line {line}: map = {m!r}: {msg}", file=ctx.source,
                            line=line, field="map") from None
    except (OSError, ValueError, MemoryError) as e:
        raise ScenarioError(f"{ctx.source} line {line}: map = {m!r}: cannot load: {e}",
                            file=ctx.source, line=line, field="map") from None
    walls = np.array(grid.walls, dtype=bool, copy=True)
    if walls.ndim != 2 or walls.size == 0:
        ctx.fail(("map",), "is empty")
    h, w = walls.shape
    if h > MAX_SIDE or w > MAX_SIDE:
        ctx.fail(("map",), f"is {w}×{h} cells, at most {MAX_SIDE}×{MAX_SIDE}")
    return walls, name


# ------------------------------------------------------------------ bundled files


def bundled_scenario_path(name: str) -> Path:
    """Path of a bundled scenario (``"demo_room"``, ``"office"``, ``"big_rooms"``)."""
    base = resources.files("robo_comp.world").joinpath("scenarios")
    p = Path(str(base)) / (name if name.endswith(".toml") else name + ".toml")
    if not p.is_file():
        raise ScenarioError(f"no bundled scenario called {name!r} (have: {', '.join(bundled_scenarios())})")
    return p


#: The scenario tests and the bench play when none is named.
DEFAULT_SCENARIO = "demo_room"


def resolve_scenario(spec: str | os.PathLike[str], base: Path | None = None) -> Path:
    """A scenario path from a path (relative to ``base``) or a bundled scenario's name."""
    p = Path(spec)
    if not p.is_absolute() and base is not None:
        p = base / p
    if p.is_file():
        return p.resolve()
    if str(spec).endswith(".toml"):  # a file name, not a bundled scenario's name
        from robo_comp.errors import FieldError

        raise FieldError(f"scenario file {spec!r} not found (looked in {p})")
    return bundled_scenario_path(str(spec))


def bundled_scenarios() -> list[str]:
    """Names of the scenarios shipped in ``robo_comp/world/scenarios``."""
    base = Path(str(resources.files("robo_comp.world").joinpath("scenarios")))
    return sorted(p.stem for p in base.glob("*.toml"))


_DEFAULT = '''
name = "Default arena"
cell_size = 25
duration = 600
seed = 1
map = { width = 24, height = 20 }

[[walls]]          # a room in the middle with a door on the south side
x = 8
y = 6
w = 8
h = 1
[[walls]]
x = 8
y = 7
w = 1
h = 6
[[walls]]
x = 15
y = 7
w = 1
h = 6
[[walls]]
x = 8
y = 13
w = 3
h = 1
[[walls]]
x = 13
y = 13
w = 3
h = 1

[[zones]]
kind = "rubble"
x = 17
y = 2
w = 4
h = 3
speed_factor = 0.5
danger = 0.2

[[victims]]
id = "v1"
x = 11
y = 9
kind = "adult"
[[victims]]
id = "v2"
x = 19
y = 10
kind = "child"
[[victims]]
id = "v3"
x = 4
y = 10
kind = "adult"

[[teams]]
name = "red"
colour = "red"
start = { x = 1, y = 1, w = 3, h = 3 }
robots = 3
[[teams]]
name = "blue"
colour = "blue"
start = { x = 20, y = 16, w = 3, h = 3 }
robots = 3
'''


def default_scenario() -> Scenario:
    """The built-in arena: 24×20 cells, a walled room with a door, a rubble zone,
    three victims and two teams (red and blue, three robots each)."""
    return parse_scenario(_DEFAULT, "<default scenario>")

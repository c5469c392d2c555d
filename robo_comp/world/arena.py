"""The simulated arena: ground truth of the room, its surfaces, victims and robots.

An :class:`Arena` stands in for the room and the robots' motors and sensors. Robots are
differential-drive: they turn on the spot at ``turn_rate`` and drive straight at
``speed`` (scaled by the surface zone they are on). In ``"grid4"`` mode (the ER1 way)
they drive from cell centre to cell centre and turn in 90° steps; in ``"free"`` mode any
heading and distance is allowed. All robots advance together in :meth:`Arena.step`,
vectorised with numpy; a robot whose front reaches a wall, the map edge or another robot
stops and a ``bump`` event is emitted.

Conventions (as in :mod:`robo_comp.world.sensors`): positions in cells with cell centres
at integer coordinates, headings in degrees with 0 = +x (east), 90 = +y (south, down the
screen), turning by a positive angle is clockwise on screen. Every random number comes
from one seeded :class:`numpy.random.Generator`.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Iterable

import numpy as np
import numpy.typing as npt

from robo_comp.errors import FieldError, NoSuchRobotError
from robo_comp.world import camera as _camera
from robo_comp.world.scenario import Scenario, Victim, Zone, default_scenario
from robo_comp.world.sensors import RangeReadings, cast_rays, sense_ranges

__all__ = ["Arena", "Event", "Pose", "COMMANDS", "BODY_REACH"]

#: Commands accepted by :meth:`Arena.command`.
COMMANDS = ("forward", "turn", "face", "goto", "halt")
#: How far ahead of its centre (cells) a robot's front reaches; it bumps when that point
#: enters a blocked cell.
BODY_REACH = 0.45
_MAX_SUBSTEP = 0.4          # cells moved per internal sub-step at most

_IDLE, _TURN, _DRIVE = 0, 1, 2


@dataclass
class Event:
    """Something that happened in the arena during :meth:`Arena.step`.

    ``kind`` is ``"bump"`` (data: x, y, heading, what = wall/robot/edge, cell, other),
    ``"done"`` (a command finished; data: command, x, y, heading) or ``"zone"`` (the
    robot entered a surface zone or left it; data: kind, danger, speed_factor, x, y,
    ``kind`` None when leaving).
    """

    kind: str
    tag: str
    time: float
    data: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form ``{"kind", "tag", "time", **data}``."""
        return {"kind": self.kind, "tag": self.tag, "time": self.time, **self.data}


@dataclass(frozen=True)
class Pose:
    """A robot's true pose: position in cells and heading in degrees [0, 360)."""

    x: float
    y: float
    heading: float

    def to_dict(self) -> dict[str, float]:
        """Plain-data form."""
        return {"x": self.x, "y": self.y, "heading": self.heading}


class Arena:
    """Ground truth of one match: grid, costs, zones, victims and robots.

    Build it from a :class:`~robo_comp.world.scenario.Scenario` (the default arena if
    none); ``seed`` overrides the scenario's seed.
    """

    # Per-robot state, one entry per slot (index = slot), grown together by :meth:`_alloc`.
    x: npt.NDArray[np.float64]
    y: npt.NDArray[np.float64]
    heading: npt.NDArray[np.float64]
    active: npt.NDArray[np.bool_]
    mode: npt.NDArray[np.int8]          # _IDLE / _TURN / _DRIVE
    target: npt.NDArray[np.float64]     # signed degrees still to turn
    remaining: npt.NDArray[np.float64]  # cells still to drive
    sign: npt.NDArray[np.float64]       # +1 forwards, -1 backwards
    bumped: npt.NDArray[np.bool_]
    odo_dist: npt.NDArray[np.float64]
    odo_turn: npt.NDArray[np.float64]
    zone: npt.NDArray[np.int32]         # index into ``zones`` of the cell under the robot, -1 none
    team_idx: npt.NDArray[np.int32]

    def __init__(self, scenario: Scenario | None = None, *, seed: int | None = None,
                 capacity: int = 16) -> None:
        self.scenario = scenario or default_scenario()
        sc = self.scenario
        #: What blocks a robot: the map's walls and the debris the map does not show.
        self.debris: np.ndarray = sc.debris_mask()
        self.walls: np.ndarray = sc.walls | self.debris
        self.height, self.width = self.walls.shape
        self.costs: np.ndarray = sc.cost_grid()
        self.cell_size = sc.cell_size
        self.victims: list[Victim] = list(sc.victims)
        self.zones: list[Zone] = list(sc.zones)
        self.rng = np.random.default_rng(sc.seed if seed is None else seed)
        self.time = 0.0
        self.speed = sc.kinematics.speed
        self.turn_rate = sc.kinematics.turn_rate
        self.drive = sc.kinematics.drive
        self._team_rgb = {t.name: t.rgb for t in sc.teams}
        # Surface grids.
        self.speed_map = np.ones(self.walls.shape, dtype=np.float64)
        self.zone_map = np.full(self.walls.shape, -1, dtype=np.int32)
        self.drops = np.zeros(self.walls.shape, dtype=bool)
        zone_rgb = np.empty(self.walls.shape + (3,), dtype=np.uint8)
        zone_rgb[:] = _camera.FLOOR
        for i, z in enumerate(self.zones):
            sl = (slice(z.rect.y, z.rect.y + z.rect.h), slice(z.rect.x, z.rect.x + z.rect.w))
            self.speed_map[sl] = np.minimum(self.speed_map[sl], z.speed_factor)
            self.zone_map[sl] = i
            if z.drop:
                self.drops[sl] = True
            zone_rgb[sl] = _camera.ZONE_COLOURS.get(z.kind, (180, 170, 140))
        self._zone_rgb = zone_rgb
        # Robot state, one slot per robot (slots are reused after remove_robot).
        self._tags: list[str | None] = []
        self._slot: dict[str, int] = {}
        #: Bodies that entered through :meth:`place` (robots this arena does not simulate or localize).
        self.placed: set[str] = set()
        self._free: list[int] = []
        self._occ = np.zeros(self.walls.shape, dtype=np.int32)   # slot + 1 of the robot in a cell
        self._pending: list[Event] = []                          # events raised outside step()
        self._alloc(capacity)

    # ----------------------------------------------------------------- storage

    def _alloc(self, cap: int) -> None:
        old = getattr(self, "_cap", 0)
        if cap <= old:
            return

        def grow(name: str, dtype: Any, fill: Any = 0) -> None:
            a = np.full(cap, fill, dtype=dtype)
            if old:
                a[:old] = getattr(self, name)
            setattr(self, name, a)

        grow("x", np.float64)
        grow("y", np.float64)
        grow("heading", np.float64)
        grow("active", bool, False)
        grow("mode", np.int8, _IDLE)
        grow("target", np.float64)
        grow("remaining", np.float64)
        grow("sign", np.float64, 1.0)
        grow("bumped", bool, False)
        grow("odo_dist", np.float64)
        grow("odo_turn", np.float64)
        grow("zone", np.int32, -1)
        grow("team_idx", np.int32, -1)
        # A robot's queue: ("cmd", kind) marks where a command starts, then its motion
        # primitives (op, value) with a number value (see _next_primitive).
        self._queues: list[deque[tuple[str, Any]]] = getattr(self, "_queues", []) + [deque() for _ in range(cap - old)]
        self._cmd: list[str | None] = getattr(self, "_cmd", []) + [None] * (cap - old)
        self._team: list[str | None] = getattr(self, "_team", []) + [None] * (cap - old)
        self._tags += [None] * (cap - old)
        self._free.extend(range(cap - 1, old - 1, -1))
        self._cap = cap

    def _tag(self, s: int) -> str:
        """The tag of the robot in slot ``s``, which must hold one (an active slot always does:
        add_robot/place set the tag with ``active``, remove_robot clears both)."""
        tag = self._tags[s]
        assert tag is not None, f"slot {s} holds no robot"
        return tag

    def _slot_of(self, tag: str) -> int:
        try:
            return self._slot[tag]
        except (KeyError, TypeError):
            raise NoSuchRobotError(f"no robot with tag {tag!r} in the arena", tag=tag) from None

    # ----------------------------------------------------------------- robots

    @property
    def tags(self) -> list[str]:
        """Tags of the robots in the arena."""
        return list(self._slot)

    def __contains__(self, tag: object) -> bool:
        return tag in self._slot

    def __len__(self) -> int:
        return len(self._slot)

    def team_of(self, tag: str) -> str:
        """The team of robot ``tag``."""
        return self._team[self._slot_of(tag)] or ""

    def free_start_cells(self, team: str) -> list[tuple[int, int]]:
        """Free cells (no wall, no robot) of ``team``'s start zone, row by row."""
        cells = self.scenario.start_cells(team)
        return [(x, y) for (x, y) in cells if self._occ[y, x] == 0]

    def is_free(self, x: int, y: int) -> bool:
        """True if cell (x, y) is inside the map, not a wall and holds no robot."""
        return (0 <= x < self.width and 0 <= y < self.height and not self.walls[y, x]
                and self._occ[y, x] == 0)

    def add_robot(self, tag: str, team: str, x: float, y: float, heading: float = 0.0) -> Pose:
        """Place robot ``tag`` of ``team`` at (x, y) facing ``heading`` degrees.

        In grid4 mode the position snaps to the cell centre and the heading to a multiple
        of 90°. Raises FieldError if the tag is taken or the cell is outside the map, a
        wall or holds another robot.
        """
        if not isinstance(tag, str) or not tag:
            raise FieldError(f"robot tag must be a non-empty string, got {tag!r}")
        if tag in self._slot:
            raise FieldError(f"a robot with tag {tag!r} is already in the arena", tag=tag)
        try:
            x, y, heading = float(x), float(y), float(heading)
        except (TypeError, ValueError):
            raise FieldError(f"robot position/heading must be numbers, got {(x, y, heading)!r}") from None
        if not all(map(math.isfinite, (x, y, heading))):
            raise FieldError("robot position/heading must be finite")
        if self.drive == "grid4":
            x, y = float(math.floor(x + 0.5)), float(math.floor(y + 0.5))
            heading = float(round(heading / 90.0) * 90.0)
        cx, cy = math.floor(x + 0.5), math.floor(y + 0.5)
        if not (0 <= cx < self.width and 0 <= cy < self.height):
            raise FieldError(f"({x:g}, {y:g}) is outside the {self.width}×{self.height} map")
        if self.walls[cy, cx]:
            raise FieldError(f"cell ({cx}, {cy}) is a wall")
        if self._occ[cy, cx]:
            other = self._tags[self._occ[cy, cx] - 1]
            raise FieldError(f"cell ({cx}, {cy}) already holds robot {other!r}")
        if not self._free:
            self._alloc(max(16, self._cap * 2))
        s = self._free.pop()
        self._slot[tag] = s
        self._tags[s] = tag
        self._team[s] = team
        self.x[s], self.y[s], self.heading[s] = x, y, heading % 360.0
        self.active[s] = True
        self.mode[s] = _IDLE
        self.remaining[s] = 0.0
        self.bumped[s] = False
        self.odo_dist[s] = self.odo_turn[s] = 0.0
        self.zone[s] = self.zone_map[cy, cx]
        self._queues[s].clear()
        self._cmd[s] = None
        self._occ[cy, cx] = s + 1
        return self.pose(tag)

    def spawn(self, tag: str, team: str, heading: float = 0.0) -> Pose:
        """Add robot ``tag`` in the first free cell of ``team``'s start zone (row by row).
        FieldError if the scenario has no such team or its start zone is full."""
        try:
            cells = self.free_start_cells(team)
        except KeyError:
            raise FieldError(f"the scenario has no team {team!r}") from None
        if not cells:
            raise FieldError(f"the start zone of team {team!r} is full")
        x, y = cells[0]
        return self.add_robot(tag, team, x, y, heading)

    def place(self, tag: str, team: str, x: float, y: float, heading: float) -> None:
        """Put the body of robot ``tag`` at (x, y, heading), adding it if it is not in the arena:
        a robot this arena does not move (a real robot, or one an overhead camera tracks). It takes
        no command; other robots' sensors and bump checks see its cell while it holds one (a cell
        already held by another robot, or a wall, stays the other's: the body is then seen only
        once it moves on). The position is kept inside the map."""
        x = min(max(float(x), -0.49), self.width - 0.51)
        y = min(max(float(y), -0.49), self.height - 0.51)
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(float(heading))):
            return
        s = self._slot.get(tag)
        if s is None:
            if not self._free:
                self._alloc(max(16, self._cap * 2))
            s = self._free.pop()
            self._slot[tag] = s
            self.placed.add(tag)
            self._tags[s] = tag
            self._team[s] = team
            self.active[s] = True
            self.remaining[s] = 0.0
            self.bumped[s] = False
            self.odo_dist[s] = self.odo_turn[s] = 0.0
            self._queues[s].clear()
            self._cmd[s] = None
        else:
            ocx, ocy = self._cell(s)
            if self._occ[ocy, ocx] == s + 1:
                self._occ[ocy, ocx] = 0
        self.mode[s] = _IDLE
        self.x[s], self.y[s], self.heading[s] = x, y, float(heading) % 360.0
        cx, cy = self._cell(s)
        self.zone[s] = self.zone_map[cy, cx]
        if self._occ[cy, cx] == 0 and not self.walls[cy, cx]:
            self._occ[cy, cx] = s + 1

    def remove_robot(self, tag: str) -> None:
        """Take robot ``tag`` out of the arena (NoSuchRobotError if absent)."""
        s = self._slot_of(tag)
        cx, cy = self._cell(s)
        if self._occ[cy, cx] == s + 1:
            self._occ[cy, cx] = 0
        self.active[s] = False
        self.mode[s] = _IDLE
        self._queues[s].clear()
        self._tags[s] = None
        self._team[s] = None
        del self._slot[tag]
        self.placed.discard(tag)
        self._free.append(s)

    def pose(self, tag: str) -> Pose:
        """The true pose of robot ``tag``."""
        s = self._slot_of(tag)
        return Pose(float(self.x[s]), float(self.y[s]), float(self.heading[s] % 360.0))

    def poses(self) -> dict[str, Pose]:
        """True poses of all robots by tag."""
        return {t: self.pose(t) for t in self._slot}

    def is_moving(self, tag: str) -> bool:
        """True while robot ``tag`` is executing a command."""
        return bool(self.mode[self._slot_of(tag)] != _IDLE)

    def idle_tags(self) -> list[str]:
        """Tags of the robots that have no command to execute (idle or stopped by a bump)."""
        idx = np.flatnonzero(self.active[: self._cap] & (self.mode[: self._cap] == _IDLE))
        return [self._tag(i) for i in idx.tolist()]

    def odometry(self, tag: str, reset: bool = True) -> tuple[float, float]:
        """(cells driven, degrees turned) by ``tag`` since the last reset -- what its wheel
        encoders measured; feed it to a :class:`~robo_comp.world.localization.DeadReckoner`."""
        s = self._slot_of(tag)
        out = (float(self.odo_dist[s]), float(self.odo_turn[s]))
        if reset:
            self.odo_dist[s] = self.odo_turn[s] = 0.0
        return out

    def slots(self, tags: list[str]) -> np.ndarray:
        """The array slots of robots ``tags`` (for the vectorised reads below)."""
        slot = self._slot
        return np.fromiter((slot[t] for t in tags), dtype=np.intp, count=len(tags))

    def take_odometry(self, slots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`odometry` of many robots at once (by :meth:`slots`), reset to zero."""
        dist, turn = self.odo_dist[slots], self.odo_turn[slots]
        self.odo_dist[slots] = 0.0
        self.odo_turn[slots] = 0.0
        return dist, turn

    def _cell(self, s: int) -> tuple[int, int]:
        return math.floor(self.x[s] + 0.5), math.floor(self.y[s] + 0.5)

    # ----------------------------------------------------------------- commands

    def command(self, tag: str, kind: str, value: Any = None, *, append: bool = False) -> None:
        """Give robot ``tag`` a motion command; it replaces the current one unless ``append``.

        ``kind``: ``"forward"`` (value: cells, negative drives backwards), ``"turn"``
        (value: degrees, positive = clockwise on screen), ``"face"`` (value: absolute
        heading), ``"goto"`` (value: (x, y); grid4 robots drive along x, then along y),
        ``"halt"`` (stop at once; the robot stays usable). In grid4 mode distances round
        to whole cells and angles to multiples of 90°. A ``done`` event follows when the
        command is finished. Raises FieldError for an unknown kind or bad value.
        """
        s = self._slot_of(tag)
        if kind not in COMMANDS:
            raise FieldError(f"unknown command {kind!r}; expected one of {', '.join(COMMANDS)}")
        grid = self.drive == "grid4"
        if kind == "halt":
            self._halt(s)
            return
        prims: list[tuple[str, float]]
        if kind in ("forward", "turn", "face"):
            v = _number(value, kind)
            if grid:
                v = float(round(v)) if kind == "forward" else float(round(v / 90.0) * 90.0)
            prims = [({"forward": "drive", "turn": "turn", "face": "face"}[kind], v)]
        else:  # goto
            try:
                gx, gy = (_number(value[0], "goto"), _number(value[1], "goto"))
            except (TypeError, IndexError, KeyError):
                raise FieldError(f"goto needs an (x, y) pair, got {value!r}") from None
            if grid:
                gx, gy = float(math.floor(gx + 0.5)), float(math.floor(gy + 0.5))
            prims = [("goto", gx), ("goto_y", gy)]
        if not append:
            self._queues[s].clear()
            self.mode[s] = _IDLE
        self._queues[s].append(("cmd", kind))
        self._queues[s].extend(prims)
        self.bumped[s] = False
        if self.mode[s] == _IDLE:
            self._emit_done(s, self._next_primitive(s), self.time, self._pending)

    def _halt(self, s: int) -> None:
        self._queues[s].clear()
        self.mode[s] = _IDLE
        self.remaining[s] = 0.0
        if self.drive == "grid4":
            self._snap(s)

    def _snap(self, s: int) -> None:
        """Snap a grid4 robot back to its cell centre and to a multiple of 90°."""
        # floor(v + 0.5), not round(): Python rounds halves to even, the occupancy grid does not.
        self.x[s] = math.floor(self.x[s] + 0.5)
        self.y[s] = math.floor(self.y[s] + 0.5)
        self.heading[s] = (round(self.heading[s] / 90.0) * 90.0) % 360.0

    def _next_primitive(self, s: int) -> list[str]:
        """Start the next motion primitive of slot ``s``; returns the kinds of the
        commands that finished on the way (for ``done`` events)."""
        q = self._queues[s]
        done: list[str] = []
        while q:
            op, v = q.popleft()
            if op == "cmd":
                prev = self._cmd[s]
                if prev is not None:
                    done.append(prev)
                self._cmd[s] = v
                continue
            if op == "drive":
                if v == 0:
                    continue
                self.mode[s] = _DRIVE
                self.remaining[s] = abs(v)
                self.sign[s] = 1.0 if v > 0 else -1.0
                return done
            if op in ("turn", "face"):
                # ``target`` holds the signed degrees still to turn: a relative turn keeps
                # its direction (turn 270 goes the long way), "face" takes the short way.
                left = v if op == "turn" else _wrap(v - self.heading[s])
                if abs(left) < 1e-9:
                    continue
                self.mode[s] = _TURN
                self.target[s] = left
                return done
            if op == "goto":
                gx, gy = v, q.popleft()[1]
                dx, dy = gx - self.x[s], gy - self.y[s]
                if self.drive == "grid4":
                    legs: list[tuple[str, float]] = []
                    if abs(dx) > 1e-9:
                        legs += [("face", 0.0 if dx > 0 else 180.0), ("drive", abs(dx))]
                    if abs(dy) > 1e-9:
                        legs += [("face", 90.0 if dy > 0 else 270.0), ("drive", abs(dy))]
                else:
                    dist = math.hypot(dx, dy)
                    legs = [("face", math.degrees(math.atan2(dy, dx)) % 360.0), ("drive", dist)] if dist > 1e-9 else []
                q.extendleft(reversed(legs))
                continue
        self.mode[s] = _IDLE
        prev = self._cmd[s]
        if prev is not None:
            done.append(prev)
        self._cmd[s] = None
        return done

    def _emit_done(self, s: int, kinds: list[str], now: float, events: list[Event]) -> None:
        for k in kinds:
            events.append(Event("done", self._tag(s), now, {
                "command": k, "x": float(self.x[s]), "y": float(self.y[s]),
                "heading": float(self.heading[s])}))

    # ----------------------------------------------------------------- simulation

    def step(self, dt: float) -> list[Event]:
        """Advance every robot by ``dt`` seconds; returns the events that happened."""
        events, self._pending = self._pending, []
        if not (dt > 0 and math.isfinite(dt)):
            return events
        fastest = self.speed * float(self.speed_map.max(initial=1.0))
        n_sub = max(1, math.ceil(fastest * dt / _MAX_SUBSTEP))
        h = dt / n_sub
        for k in range(n_sub):
            self._substep(h, self.time + h * (k + 1), events)
        self.time += dt
        self._zone_events(events)
        return events

    def _substep(self, h: float, now: float, events: list[Event]) -> None:
        finished: list[int] = []
        # Turning robots.
        ti = np.flatnonzero(self.mode[: self._cap] == _TURN)
        if ti.size:
            left = self.target[ti]
            lim = self.turn_rate * h
            stepv = _clamp(left, -lim, lim)
            done = np.abs(left) <= lim + 1e-9
            stepv = np.where(done, left, stepv)
            self.heading[ti] = (self.heading[ti] + stepv) % 360.0
            self.target[ti] = left - stepv
            self.odo_turn[ti] += stepv
            finished.extend(ti[done].tolist())
        # Driving robots.
        di = np.flatnonzero(self.mode[: self._cap] == _DRIVE)
        if di.size:
            self._drive(di, h, now, events, finished)
        for s in finished:
            if self.mode[s] == _IDLE:
                continue
            self.mode[s] = _IDLE
            if self.drive == "grid4":
                self._snap(s)
            self._emit_done(s, self._next_primitive(s), now, events)

    def _drive(self, di: np.ndarray, h: float, now: float, events: list[Event],
               finished: list[int]) -> None:
        W, H = self.width, self.height
        x, y = self.x[di], self.y[di]
        ocx = np.floor(x + 0.5).astype(np.int64)
        ocy = np.floor(y + 0.5).astype(np.int64)
        sf = self.speed_map[_clamp(ocy, 0, H - 1), _clamp(ocx, 0, W - 1)]
        d = np.minimum(self.remaining[di], self.speed * sf * h)
        hr = np.radians(self.heading[di])
        ux = np.cos(hr) * self.sign[di]
        uy = np.sin(hr) * self.sign[di]
        nx, ny = x + d * ux, y + d * uy
        ncx = np.floor(nx + 0.5).astype(np.int64)
        ncy = np.floor(ny + 0.5).astype(np.int64)
        pcx = np.floor(nx + BODY_REACH * ux + 0.5).astype(np.int64)
        pcy = np.floor(ny + BODY_REACH * uy + 0.5).astype(np.int64)
        out = (pcx < 0) | (pcx >= W) | (pcy < 0) | (pcy >= H) | (ncx < 0) | (ncx >= W) | (ncy < 0) | (ncy >= H)
        pcxc, pcyc = _clamp(pcx, 0, W - 1), _clamp(pcy, 0, H - 1)
        ncxc, ncyc = _clamp(ncx, 0, W - 1), _clamp(ncy, 0, H - 1)
        hit_wall = out | self.walls[pcyc, pcxc] | self.walls[ncyc, ncxc]
        me = di + 1
        occ_p = self._occ[pcyc, pcxc]
        occ_n = self._occ[ncyc, ncxc]
        hit_robot = ~hit_wall & (((occ_p != 0) & (occ_p != me)) | ((occ_n != 0) & (occ_n != me)))
        moving = ~(hit_wall | hit_robot)
        # Two robots entering the same free cell in the same sub-step: the first wins.
        change = moving & ((ncx != ocx) | (ncy != ocy))
        if change.any():
            ci = np.flatnonzero(change)
            lin = ncyc[ci] * W + ncxc[ci]
            _, first = np.unique(lin, return_index=True)
            loser = np.ones(ci.size, dtype=bool)
            loser[first] = False
            if loser.any():
                moving[ci[loser]] = False
                hit_robot[ci[loser]] = True
                change[ci[loser]] = False
            ci = np.flatnonzero(change)
            self._occ[ocy[ci], ocx[ci]] = 0
            self._occ[ncyc[ci], ncxc[ci]] = di[ci] + 1
        mi = di[moving]
        self.x[mi] = nx[moving]
        self.y[mi] = ny[moving]
        self.remaining[mi] -= d[moving]
        self.odo_dist[mi] += d[moving] * self.sign[mi]
        arrived = moving & (self.remaining[di] <= 1e-9)
        finished.extend(di[arrived].tolist())
        bumped = np.flatnonzero(~moving)
        for j in bumped.tolist():
            s = int(di[j])
            what = "edge" if out[j] else ("wall" if hit_wall[j] else "robot")
            other = None
            if what == "robot":
                o = occ_p[j] if occ_p[j] not in (0, s + 1) else occ_n[j]
                other = self._tags[o - 1] if o else None
            self._queues[s].clear()
            self.mode[s] = _IDLE
            self.remaining[s] = 0.0
            self.bumped[s] = True
            if self.drive == "grid4":
                self._snap(s)
            self._cmd[s] = None
            events.append(Event("bump", self._tag(s), now, {
                "x": float(self.x[s]), "y": float(self.y[s]), "heading": float(self.heading[s]),
                "what": what, "cell": [int(pcx[j]), int(pcy[j])], "other": other}))

    def _zone_events(self, events: list[Event]) -> None:
        idx = np.flatnonzero(self.active[: self._cap])
        if not idx.size:
            return
        cx = _clamp(np.floor(self.x[idx] + 0.5).astype(np.int64), 0, self.width - 1)
        cy = _clamp(np.floor(self.y[idx] + 0.5).astype(np.int64), 0, self.height - 1)
        z = self.zone_map[cy, cx]
        changed = z != self.zone[idx]
        for j in np.flatnonzero(changed).tolist():
            s = int(idx[j])
            zi = int(z[j])
            self.zone[s] = zi
            zone = self.zones[zi] if zi >= 0 else None
            events.append(Event("zone", self._tag(s), self.time, {
                "kind": zone.kind if zone else None, "name": zone.name if zone else None,
                "danger": zone.danger if zone else 0.0,
                "speed_factor": zone.speed_factor if zone else 1.0,
                "x": float(self.x[s]), "y": float(self.y[s])}))

    # ----------------------------------------------------------------- sensing

    def surface(self, x: float, y: float) -> dict[str, Any]:
        """Context information of the cell holding (x, y): wall, cost, zone kind, speed
        factor, danger, drop (plain data)."""
        cx, cy = math.floor(x + 0.5), math.floor(y + 0.5)
        if not (0 <= cx < self.width and 0 <= cy < self.height):
            raise FieldError(f"({x:g}, {y:g}) is outside the {self.width}×{self.height} map")
        zi = int(self.zone_map[cy, cx])
        z = self.zones[zi] if zi >= 0 else None
        return {"x": cx, "y": cy, "wall": bool(self.walls[cy, cx]), "cost": float(self.costs[cy, cx]),
                "zone": z.kind if z else None, "speed_factor": float(self.speed_map[cy, cx]),
                "danger": z.danger if z else 0.0, "drop": bool(self.drops[cy, cx])}

    def _blocked(self) -> np.ndarray:
        return self.walls | (self._occ != 0)

    def sense_all(self, tags: Iterable[str] | None = None) -> tuple[list[str], RangeReadings]:
        """Range readings (cm) of many robots at once -- all robots if ``tags`` is None.
        Returns (tags, readings) with one row per tag; used by the bench and the core."""
        if tags is None:
            idx = np.flatnonzero(self.active[: self._cap])
            tl = [self._tag(i) for i in idx.tolist()]
        else:
            tl = list(tags)
            idx = np.array([self._slot_of(t) for t in tl], dtype=np.int64)
        r = sense_ranges(self._blocked(), self.drops, self.x[idx], self.y[idx], self.heading[idx],
                         self.scenario.sensors, self.cell_size, self.rng)
        return tl, r

    def sense(self, tag: str) -> dict[str, Any]:
        """Sensor readings of robot ``tag``: ``front``/``left``/``right``/``down`` in cm
        (``None`` = no echo within range), ``bump`` (its last move ended in a collision),
        ``moving``, ``zone`` (surface kind under it) and ``time``."""
        return self.sense_many([tag])[0]

    def sense_many(self, tags: list[str]) -> list[dict[str, Any]]:
        """:meth:`sense` for several robots in one vectorised pass (a host reports many at once)."""
        _, r = self.sense_all(tags)
        out = []
        for i, tag in enumerate(tags):
            s = self._slot_of(tag)
            row: dict[str, Any] = r.row(i)
            cx, cy = self._cell(s)
            zi = int(self.zone_map[min(max(cy, 0), self.height - 1), min(max(cx, 0), self.width - 1)])
            row.update(bump=bool(self.bumped[s]), moving=bool(self.mode[s] != _IDLE),
                       zone=self.zones[zi].kind if zi >= 0 else None, time=self.time)
            out.append(row)
        return out

    def _view(self, s: int) -> _camera.CameraView:
        robots = [(float(self.x[o]), float(self.y[o]), self._team_rgb.get(self._team[o] or "", (128, 128, 128)))
                  for o in np.flatnonzero(self.active[: self._cap]).tolist() if o != s]
        return _camera.CameraView(self.walls, self._zone_rgb, robots,
                                  [(float(v.x), float(v.y)) for v in self.victims])

    def camera_image(self, tag: str) -> np.ndarray:
        """The camera picture of robot ``tag`` as an (64, 96, 3) uint8 array."""
        s = self._slot_of(tag)
        cam = self.scenario.camera
        return _camera.render_view(self._view(s), float(self.x[s]), float(self.y[s]),
                                   float(self.heading[s]), cam.fov, cam.range)

    def camera(self, tag: str) -> bytes:
        """The camera picture of robot ``tag`` as PNG bytes (96×64 RGB, forward is up)."""
        return _camera.encode_png(self.camera_image(tag))

    def victims_in_view(self, tag: str) -> list[Victim]:
        """Victims inside robot ``tag``'s camera field of view, within range and not
        hidden behind walls (ground truth, for scoring)."""
        s = self._slot_of(tag)
        if not self.victims:
            return []
        cam = self.scenario.camera
        x0, y0, hd = float(self.x[s]), float(self.y[s]), float(self.heading[s])
        vx = np.array([v.x for v in self.victims], dtype=np.float64)
        vy = np.array([v.y for v in self.victims], dtype=np.float64)
        dist = np.hypot(vx - x0, vy - y0)
        ang = np.abs(_wrap(np.degrees(np.arctan2(vy - y0, vx - x0)) - hd))
        cand = (dist <= cam.range) & ((ang <= cam.fov / 2) | (dist < 0.5))
        if cand.any():
            los = _camera.line_of_sight(self.walls, x0, y0, vx[cand], vy[cand])
            cand[np.flatnonzero(cand)[~los]] = False
        return [v for v, c in zip(self.victims, cand.tolist()) if c]

    def truth(self) -> dict[str, Any]:
        """Ground truth as plain data (for the referee and replays): time, robots, victims."""
        return {"time": self.time,
                "robots": [{"tag": t, "team": self.team_of(t), **self.pose(t).to_dict()} for t in self._slot],
                "victims": [v.to_dict() for v in self.victims]}

    def driving_into(self, tag: str, x: int, y: int) -> bool:
        """Whether another robot is in cell ``(x, y)`` or driving into it now (it stands in a
        neighbouring cell and drives towards it): what robot ``tag``'s range sensors and its eyes on
        the robots next to it would tell."""
        me = self._slot_of(tag)
        if 0 <= x < self.width and 0 <= y < self.height and int(self._occ[y, x]) - 1 not in (-1, me):
            return True
        for nx, ny in ((x + 1, y), (x - 1, y), (x, y + 1), (x, y - 1)):
            if not (0 <= nx < self.width and 0 <= ny < self.height):
                continue
            o = int(self._occ[ny, nx]) - 1
            if o < 0 or o == me or self.mode[o] != _DRIVE:
                continue
            hr = math.radians(float(self.heading[o])) if self.sign[o] > 0 else math.radians(float(self.heading[o]) + 180.0)
            if math.cos(hr) * (x - nx) + math.sin(hr) * (y - ny) > 0.7:  # within 45 degrees of the cell
                return True
        return False

    def clearance(self, tag: str, heading: float, max_cells: float = 4.0) -> float:
        """How far (cells) robot ``tag`` can drive along ``heading`` before its front reaches a
        wall or another robot: what its front range sensor reads, less its reach (``max_cells``
        when nothing is that near)."""
        s = self._slot_of(tag)
        d = float(cast_rays(self._blocked(), self.x[s:s + 1], self.y[s:s + 1], np.array([math.radians(heading)]),
                            max_cells + BODY_REACH)[0])
        return min(max_cells, d - BODY_REACH)

    # for the ray caster users
    def ray_distance(self, x: float, y: float, heading: float, max_cells: float = 1000.0) -> float:
        """Distance in cells from (x, y) along ``heading`` to the first wall (``inf`` if none)."""
        return float(cast_rays(self.walls, np.array([x]), np.array([y]),
                               np.array([math.radians(heading)]), max_cells)[0])


def _clamp(a: Any, lo: Any, hi: Any) -> Any:
    """``np.clip(a, lo, hi)`` for ``lo <= hi``, the same values: numpy 2's ``clip`` costs a few
    microseconds of Python around the ufunc, several times two ufunc calls on the arena's small
    arrays (and the arena calls it every sub-step)."""
    return np.minimum(np.maximum(a, lo), hi)


def _wrap(a: Any) -> Any:
    """Wrap degrees into [-180, 180)."""
    return (np.asarray(a) + 180.0) % 360.0 - 180.0 if isinstance(a, np.ndarray) else (a + 180.0) % 360.0 - 180.0


def _number(v: Any, kind: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise FieldError(f"{kind} needs a number, got {v!r}")
    f = float(v)
    if not math.isfinite(f) or abs(f) > 1e7:
        raise FieldError(f"{kind} value {v!r} is out of range")
    return f

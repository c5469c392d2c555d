"""The map service: the map as known by the environment, served whole, in pieces or as deltas.

It holds what the thesis's map service held (sections 2.2.2, 3.2.2): the size, walls and
cell costs of the work space, surface zones, known objects, the positions robots report
(estimates, never ground truth) and the objects robots discover with their evidence.

* :meth:`MapService.snapshot` -- the whole map as one team (or the referee, ``team=None``)
  may see it.
* :meth:`MapService.piece` -- the window around a robot with the cells that lie in other
  robots' pieces marked ``shared`` (thesis section 7.5).
* :meth:`MapService.delta_since` -- what changed since a version; a client keeps a
  :class:`MapView` and calls :meth:`MapView.apply` on every delta, and its
  :meth:`MapView.snapshot` then equals the service's snapshot for its team.
* :meth:`MapService.add_obstacle` -- a cell a team's robot reported blocked where the map shows it
  free (``obstacles``, ``[x, y]`` each): on that team's map (everyone's when discoveries are
  shared); its planners route around it.

Discoveries are visible to the discovering team and the referee only, unless the
scenario says ``shared_discoveries``. Everything returned is plain data -- dicts, lists,
numbers, strings and bytes -- that msgpack can carry; grids travel as
``{"shape": [h, w], "bits": np.packbits(...)}`` and costs as float32 bytes.
"""
from __future__ import annotations

import bisect
import math
from typing import Any, Iterable

import numpy as np

from robo_comp.errors import FieldError, NoSuchRobotError
from robo_comp.world.scenario import Scenario, Zone, compute_costs

__all__ = ["MapService", "MapView", "pack_bits", "unpack_bits", "pack_costs", "unpack_costs"]

REFEREE = None  #: ``team`` value that sees everything (referee, display wall)


def pack_bits(mask: np.ndarray) -> dict[str, Any]:
    """A bool grid as plain data ``{"shape": [h, w], "bits": bytes}`` (np.packbits, row-major)."""
    m = np.asarray(mask, dtype=bool)
    return {"shape": [int(s) for s in m.shape], "bits": np.packbits(m.reshape(-1)).tobytes()}


def unpack_bits(data: dict[str, Any]) -> np.ndarray:
    """Inverse of :func:`pack_bits`."""
    h, w = (int(s) for s in data["shape"])
    bits = np.frombuffer(bytes(data["bits"]), dtype=np.uint8)
    return np.unpackbits(bits, count=h * w).astype(bool).reshape(h, w)


def pack_costs(costs: np.ndarray) -> dict[str, Any]:
    """A cost grid as plain data ``{"shape": [h, w], "dtype": "float32", "data": bytes}``."""
    c = np.ascontiguousarray(costs, dtype="<f4")
    return {"shape": [int(s) for s in c.shape], "dtype": "float32", "data": c.tobytes()}


def unpack_costs(data: dict[str, Any]) -> np.ndarray:
    """Inverse of :func:`pack_costs` (float32 array)."""
    h, w = (int(s) for s in data["shape"])
    return np.frombuffer(bytes(data["data"]), dtype="<f4").reshape(h, w).copy()


class MapService:
    """The environment's map with versioned change tracking and per-team visibility.

    Every change bumps :attr:`version`. Visibility of an entity is ``None`` (everyone)
    or a team name; the referee (``team=None``) sees everything.
    """

    def __init__(self, walls: np.ndarray, *, cell_size: float = 25.0, costs: np.ndarray | None = None,
                 zones: Iterable[Zone] = (), shared_discoveries: bool = False,
                 share_robot_positions: bool = True, scenario: Scenario | None = None) -> None:
        self.walls = np.array(walls, dtype=bool, copy=True)
        self.height, self.width = self.walls.shape
        self.cell_size = float(cell_size)
        self.scenario = scenario
        self.zones = list(zones)
        self.costs = (np.array(costs, dtype=np.float32, copy=True) if costs is not None
                      else self._compute_costs())
        self.shared_discoveries = shared_discoveries
        self.share_robot_positions = share_robot_positions
        self.version = 1
        #: The version of the newest change that is not a robot's position.
        self.static_version = 1
        # key -> (version, visibility, value or None when deleted)
        self._ent: dict[tuple, tuple[int, str | None, Any]] = {}
        self._log_v: list[int] = []
        self._log_k: list[tuple] = []
        self._by_kind: dict[str, dict[tuple, None]] = {}
        self._next_disc = 1

    @classmethod
    def from_scenario(cls, scenario: Scenario, **kw: Any) -> "MapService":
        """A map service holding the scenario's map, costs, zones and known objects
        (victims are not put on the map: they are to be found)."""
        svc = cls(scenario.walls, cell_size=scenario.cell_size, costs=scenario.cost_grid(),
                  zones=scenario.zones, shared_discoveries=scenario.shared_discoveries,
                  scenario=scenario, **kw)
        for o in scenario.objects:
            svc.add_object(o.id, o.kind, o.x, o.y, o.description)
        return svc

    def _compute_costs(self) -> np.ndarray:
        from robo_comp.world.scenario import CostConfig
        cfg = self.scenario.costs if self.scenario is not None else CostConfig()
        return compute_costs(self.walls, cfg, self.zones).astype(np.float32)

    # ------------------------------------------------------------- change log

    def _touch(self, key: tuple, value: Any, visibility: str | None) -> None:
        self.version += 1
        if key[0] != "robot":
            self.static_version = self.version
        self._ent[key] = (self.version, visibility, value)
        self._by_kind.setdefault(key[0], {})[key] = None
        self._log_v.append(self.version)
        self._log_k.append(key)
        if len(self._log_k) > max(4096, 4 * len(self._ent)):
            self._compact()

    def _compact(self) -> None:
        items = sorted(((v, k) for k, (v, _, _) in self._ent.items()))
        self._log_v = [v for v, _ in items]
        self._log_k = [k for _, k in items]

    @staticmethod
    def _visible(visibility: str | None, team: str | None) -> bool:
        return team is None or visibility is None or visibility == team

    def _items(self, kind: str, team: str | None) -> list[Any]:
        out = []
        for k in self._by_kind.get(kind, ()):
            _, vis, val = self._ent[k]
            if val is not None and self._visible(vis, team):
                out.append((k[1], val))
        out.sort(key=lambda kv: kv[0])
        return [v for _, v in out]

    # ------------------------------------------------------------- updates

    def set_walls(self, cells: Iterable[tuple[int, int]], blocked: bool = True) -> int:
        """Block (or clear) cells; costs around them are recomputed. Returns how many
        cells changed (wall or cost)."""
        old_w = self.walls.copy()
        for x, y in cells:
            x, y = int(x), int(y)
            if not (0 <= x < self.width and 0 <= y < self.height):
                raise FieldError(f"cell ({x}, {y}) is outside the {self.width}×{self.height} map")
            self.walls[y, x] = bool(blocked)
        if np.array_equal(old_w, self.walls):
            return 0
        new_c = self._compute_costs()
        changed = np.flatnonzero(((old_w != self.walls) | (new_c != self.costs)).reshape(-1))
        self.costs = new_c
        for i in changed.tolist():
            y, x = divmod(i, self.width)
            self._touch(("cell", i), [x, y, bool(self.walls[y, x]), float(self.costs[y, x])], None)
        return int(changed.size)

    def set_wall(self, x: int, y: int, blocked: bool = True) -> int:
        """Block (or clear) one cell; see :meth:`set_walls`."""
        return self.set_walls([(x, y)], blocked)

    def report_position(self, tag: str, team: str, x: float, y: float, heading: float = 0.0,
                        time: float = 0.0) -> None:
        """Record the reported (estimated) pose of robot ``tag`` of ``team``."""
        vals = (float(x), float(y), float(heading), float(time))
        if not all(map(math.isfinite, vals)):
            raise FieldError("position, heading and time must be finite numbers")
        rec = {"tag": tag, "team": team, "x": vals[0], "y": vals[1], "heading": vals[2] % 360.0,
               "time": vals[3]}
        self._touch(("robot", tag), rec, None if self.share_robot_positions else team)

    def remove_robot(self, tag: str) -> None:
        """Forget robot ``tag`` (it left the arena)."""
        e = self._ent.get(("robot", tag))
        if e is None or e[2] is None:
            raise NoSuchRobotError(f"no robot {tag!r} on the map", tag=tag)
        self._touch(("robot", tag), None, e[1])

    def robot(self, tag: str) -> dict[str, Any]:
        """The last reported record of robot ``tag``."""
        e = self._ent.get(("robot", tag))
        if e is None or e[2] is None:
            raise NoSuchRobotError(f"no robot {tag!r} on the map", tag=tag)
        return dict(e[2])

    def add_object(self, obj_id: str, kind: str, x: int, y: int, description: str = "") -> dict[str, Any]:
        """Add (or replace) a known object visible to everyone."""
        self._check_cell(x, y)
        rec = {"id": obj_id, "kind": kind, "x": int(x), "y": int(y), "description": description}
        self._touch(("object", obj_id), rec, None)
        return dict(rec)

    def remove_object(self, obj_id: str) -> None:
        """Remove a known object (KeyError-free: FieldError if unknown)."""
        e = self._ent.get(("object", obj_id))
        if e is None or e[2] is None:
            raise FieldError(f"no object {obj_id!r} on the map")
        self._touch(("object", obj_id), None, None)

    def add_discovery(self, finder: str, team: str, x: float, y: float, time: float,
                      kind: str = "victim", evidence: Iterable[str] = (), note: str = "",
                      disc_id: str | None = None) -> dict[str, Any]:
        """Record an object robot ``finder`` of ``team`` discovered at (x, y) at ``time``
        with ``evidence`` (picture/upload ids). Visible to ``team`` and the referee
        (everyone if discoveries are shared). Returns the record (with its ``id``)."""
        self._check_cell(round(x), round(y))
        if disc_id is None:
            disc_id = f"d{self._next_disc}"
            self._next_disc += 1
        if ("discovery", disc_id) in self._ent:
            raise FieldError(f"discovery {disc_id!r} exists already")
        rec: dict[str, Any] = {"id": disc_id, "finder": finder, "team": team, "x": float(x), "y": float(y),
               "time": float(time), "kind": kind, "evidence": [str(e) for e in evidence], "note": note}
        self._touch(("discovery", disc_id), rec, None if self.shared_discoveries else team)
        return dict(rec, evidence=list(rec["evidence"]))

    def add_evidence(self, disc_id: str, evidence_id: str) -> dict[str, Any]:
        """Attach another piece of evidence (e.g. a picture id) to a discovery."""
        e = self._ent.get(("discovery", disc_id))
        if e is None or e[2] is None:
            raise FieldError(f"no discovery {disc_id!r}")
        rec = dict(e[2], evidence=list(e[2]["evidence"]) + [str(evidence_id)])
        self._touch(("discovery", disc_id), rec, e[1])
        return dict(rec)

    def discovery(self, disc_id: str, team: str | None = None) -> dict[str, Any]:
        """One discovery as ``team`` may see it (FieldError if absent or not visible)."""
        e = self._ent.get(("discovery", disc_id))
        if e is None or e[2] is None or not self._visible(e[1], team):
            raise FieldError(f"no discovery {disc_id!r}")
        return dict(e[2], evidence=list(e[2]["evidence"]))

    def add_obstacle(self, team: str, x: int, y: int) -> bool:
        """Put cell ``(x, y)``, which a robot of ``team`` reported blocked, on ``team``'s map
        (everyone's if discoveries are shared); False if it was there already."""
        self._check_cell(x, y)
        key = ("obstacle", f"{team}:{x}:{y}")
        if key in self._ent:
            return False
        self._touch(key, [int(x), int(y)], None if self.shared_discoveries else team)
        return True

    def _check_cell(self, x: int, y: int) -> None:
        if not (0 <= x < self.width and 0 <= y < self.height):
            raise FieldError(f"cell ({x}, {y}) is outside the {self.width}×{self.height} map")

    # ------------------------------------------------------------- reading

    def snapshot(self, team: str | None = None) -> dict[str, Any]:
        """The whole map as ``team`` sees it (``None`` = referee: everything)."""
        return {
            "type": "full", "version": self.version, "width": self.width, "height": self.height,
            "cell_size": self.cell_size, "walls": pack_bits(self.walls), "costs": pack_costs(self.costs),
            "zones": [z.to_dict() for z in self.zones],
            "objects": self._items("object", team), "robots": self._items("robot", team),
            "discoveries": [dict(d, evidence=list(d["evidence"])) for d in self._items("discovery", team)],
            "obstacles": sorted({tuple(c) for c in self._items("obstacle", team)}),
        }

    def delta_since(self, version: int, team: str | None = None, robots: bool = True) -> dict[str, Any]:
        """Changes after ``version`` as ``team`` sees them (without robot positions when
        ``robots`` is false). A version of 0 (or one the service does not know, e.g. after a
        restart) gets a full snapshot instead."""
        if not isinstance(version, int) or version <= 0 or version > self.version:
            return self.snapshot(team)
        i = bisect.bisect_right(self._log_v, version)
        keys = dict.fromkeys(k for k in self._log_k[i:] if robots or k[0] != "robot")
        if len(keys) > self.width * self.height // 2:
            return self.snapshot(team)
        out: dict[str, Any] = {"type": "delta", "from": version, "version": self.version,
                               "cells": [], "robots": [], "removed_robots": [], "objects": [],
                               "removed_objects": [], "discoveries": [], "obstacles": []}
        for key in keys:
            v, vis, val = self._ent[key]
            if v <= version or not self._visible(vis, team):
                continue
            kind = key[0]
            if kind == "robot" and not robots:
                continue
            if kind == "cell":
                out["cells"].append(list(val))
            elif kind == "robot":
                (out["robots"].append(dict(val)) if val is not None else out["removed_robots"].append(key[1]))
            elif kind == "object":
                (out["objects"].append(dict(val)) if val is not None else out["removed_objects"].append(key[1]))
            elif kind == "discovery":
                out["discoveries"].append(dict(val, evidence=list(val["evidence"])))
            elif kind == "obstacle":
                out["obstacles"].append(list(val))
        return out

    def piece(self, tag: str, radius: int, team: str | None = None) -> dict[str, Any]:
        """The map window of ``radius`` cells around robot ``tag``'s reported position
        (clipped at the map edge) as ``team`` sees it, with ``shared`` marking the cells
        that also lie in another robot's window of the same radius (thesis 7.5)."""
        rec = self.robot(tag)
        if not isinstance(radius, int) or isinstance(radius, bool) or not 0 <= radius <= 10_000:
            raise FieldError(f"radius must be a whole number 0..10000, got {radius!r}")
        cx, cy = int(math.floor(rec["x"] + 0.5)), int(math.floor(rec["y"] + 0.5))
        x0, y0 = max(0, cx - radius), max(0, cy - radius)
        x1, y1 = min(self.width, cx + radius + 1), min(self.height, cy + radius + 1)
        shared = np.zeros((max(0, y1 - y0), max(0, x1 - x0)), dtype=bool)
        robots = []
        for other in self._items("robot", None):
            ox, oy = int(math.floor(other["x"] + 0.5)), int(math.floor(other["y"] + 0.5))
            if other["tag"] != tag:
                ax0, ay0 = max(x0, ox - radius), max(y0, oy - radius)
                ax1, ay1 = min(x1, ox + radius + 1), min(y1, oy + radius + 1)
                if ax0 < ax1 and ay0 < ay1:
                    shared[ay0 - y0:ay1 - y0, ax0 - x0:ax1 - x0] = True
            if x0 <= ox < x1 and y0 <= oy < y1 and self._visible(
                    None if self.share_robot_positions else other["team"], team):
                robots.append(dict(other))

        def inside(d: dict) -> bool:
            px, py = math.floor(d["x"] + 0.5), math.floor(d["y"] + 0.5)
            return x0 <= px < x1 and y0 <= py < y1

        zones = [z.to_dict() for z in self.zones
                 if z.rect.x < x1 and x0 < z.rect.x + z.rect.w and z.rect.y < y1 and y0 < z.rect.y + z.rect.h]
        return {
            "type": "piece", "version": self.version, "tag": tag, "x0": x0, "y0": y0,
            "width": x1 - x0, "height": y1 - y0, "cell_size": self.cell_size,
            "walls": pack_bits(self.walls[y0:y1, x0:x1]), "costs": pack_costs(self.costs[y0:y1, x0:x1]),
            "shared": pack_bits(shared), "zones": zones,
            "objects": [o for o in self._items("object", team) if inside(o)],
            "robots": robots,
            "discoveries": [d for d in self._items("discovery", team) if inside(d)],
        }


class MapView:
    """A client's copy of the map, kept current with :meth:`apply` on the service's
    snapshots and deltas (what a robot or a team console holds)."""

    def __init__(self) -> None:
        self.version = 0
        self.width = self.height = 0
        self.cell_size = 0.0
        self.walls = np.zeros((0, 0), dtype=bool)
        self.costs = np.zeros((0, 0), dtype=np.float32)
        self.zones: list[dict[str, Any]] = []
        self.objects: dict[str, dict[str, Any]] = {}
        self.robots: dict[str, dict[str, Any]] = {}
        self.discoveries: dict[str, dict[str, Any]] = {}
        #: Cells the team's robots reported blocked (the map's walls do not show them).
        self.obstacles: set[tuple[int, int]] = set()

    def apply(self, delta: dict[str, Any]) -> None:
        """Apply a snapshot (``type == "full"``) or a delta (``type == "delta"``).
        A delta whose ``from`` is newer than this view's version raises FieldError: ask
        the service for ``delta_since(view.version)`` instead."""
        kind = delta.get("type")
        if kind == "full":
            self.width, self.height = int(delta["width"]), int(delta["height"])
            self.cell_size = float(delta["cell_size"])
            self.walls = unpack_bits(delta["walls"])
            self.costs = unpack_costs(delta["costs"])
            self.zones = [dict(z) for z in delta["zones"]]
            self.objects = {o["id"]: dict(o) for o in delta["objects"]}
            self.robots = {r["tag"]: dict(r) for r in delta["robots"]}
            self.discoveries = {d["id"]: dict(d, evidence=list(d["evidence"])) for d in delta["discoveries"]}
            self.obstacles = {(int(c[0]), int(c[1])) for c in delta.get("obstacles", ())}
            self.version = int(delta["version"])
            return
        if kind != "delta":
            raise FieldError(f"not a map snapshot or delta (type {kind!r})")
        if int(delta["from"]) > self.version:
            raise FieldError(f"delta from version {delta['from']} does not follow view version {self.version}")
        for x, y, wall, cost in delta["cells"]:
            self.walls[y, x] = wall
            self.costs[y, x] = cost
        for r in delta["robots"]:
            self.robots[r["tag"]] = dict(r)
        for t in delta["removed_robots"]:
            self.robots.pop(t, None)
        for o in delta["objects"]:
            self.objects[o["id"]] = dict(o)
        for oid in delta["removed_objects"]:
            self.objects.pop(oid, None)
        for d in delta["discoveries"]:
            self.discoveries[d["id"]] = dict(d, evidence=list(d["evidence"]))
        for c in delta.get("obstacles", ()):
            self.obstacles.add((int(c[0]), int(c[1])))
        self.version = max(self.version, int(delta["version"]))

    def snapshot(self) -> dict[str, Any]:
        """This view in the form of :meth:`MapService.snapshot` (for comparison)."""
        return {
            "type": "full", "version": self.version, "width": self.width, "height": self.height,
            "cell_size": self.cell_size, "walls": pack_bits(self.walls), "costs": pack_costs(self.costs),
            "zones": [dict(z) for z in self.zones],
            "objects": [self.objects[k] for k in sorted(self.objects)],
            "robots": [self.robots[k] for k in sorted(self.robots)],
            "discoveries": [self.discoveries[k] for k in sorted(self.discoveries)],
            "obstacles": sorted(self.obstacles),
        }

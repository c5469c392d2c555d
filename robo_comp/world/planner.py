"""Grid path planning: optimal A* (compiled with numba), connectivity and a hierarchical mode.

Coordinates are ``(x, y)``; wall arrays are indexed ``[y, x]`` with True = blocked.
Moves are 4-connected, or 8-connected with diagonal step √2 and no corner cutting (a
diagonal needs both orthogonal neighbours free, the Moving AI convention). The cost of a
move is its step length times the cost of the cell entered (costs ≥ 1, normal 1).

Importing this module is cheap: numba and the kernels load on the first query, and the
compiled kernels are cached on disk (``cache=True``) so later processes skip compiling.
"""
from __future__ import annotations

import math
import mmap
import threading
from typing import Any

import numpy as np

from robo_comp.world.paths import Cell, PathResult
from robo_comp.world.paths import kernels as _k

def warm_up(jumps: bool = True) -> float:
    """Compile (or load from cache) every kernel now; returns the seconds it took. ``jumps=False``
    leaves out jump point search (8 directions, uniform cost), which the project's robots never
    run: a robot host or league worker starting on a fresh install then does not compile it."""
    import time

    t0 = time.perf_counter()
    walls = np.zeros((4, 4), dtype=bool)
    walls[1, 1:3] = True
    Planner(walls).find((0, 0), (3, 3))
    Planner(walls, diagonal=True, costs=np.ones((4, 4))).find((0, 0), (3, 3))
    if jumps:
        Planner(walls, diagonal=True).find((0, 0), (3, 3))
    p = Planner(walls, hierarchical=True, block=2)
    p.find((0, 0), (3, 3))
    p.reachable((0, 0), (3, 3))
    find_path(walls, (0, 0), (3, 3))
    _k().connected(p._free, 4, 4, 0, 15)
    return time.perf_counter() - t0


def obstacle_costs(walls: np.ndarray, near_cost: float = 10.0, radius: int = 1) -> np.ndarray:
    """Thesis-style cell costs: 1 for normal cells, ``near_cost`` for free cells within
    ``radius`` cells (Chebyshev distance) of a wall. Walls themselves get 1 (never entered)."""
    walls = np.asarray(walls, dtype=bool)
    h, w = walls.shape
    near = np.zeros_like(walls)
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            if dx == 0 and dy == 0:
                continue
            ys = slice(max(dy, 0), h + min(dy, 0))
            yd = slice(max(-dy, 0), h + min(-dy, 0))
            xs = slice(max(dx, 0), w + min(dx, 0))
            xd = slice(max(-dx, 0), w + min(-dx, 0))
            near[yd, xd] |= walls[ys, xs]
    costs = np.ones(walls.shape, dtype=np.float64)
    costs[near & ~walls] = float(near_cost)
    return costs


def _lazy_zeros(n: int, dtype: type) -> np.ndarray:
    """A zeroed array of ``n`` items whose pages the OS maps only when first touched.

    numpy asks the kernel for 2 MiB huge pages (``madvise``) from 4 MiB up, so a search that
    runs down a column of a big map would materialise 2 MiB for every few cells it touches
    (hundreds of MiB for a search of thousands of cells); from there on an anonymous
    ``mmap`` gets 4 KiB pages, zeroed by the OS on first touch. Below it ``np.zeros`` is
    kept: the C library recycles such blocks between one-off queries, already mapped.
    """
    dt = np.dtype(dtype)
    size = n * dt.itemsize
    if size < (1 << 22):
        return np.zeros(n, dtype=dt)
    return np.frombuffer(mmap.mmap(-1, size), dtype=dt)


def _check_cell(cell: Cell, w: int, h: int, what: str) -> tuple[int, int]:
    try:
        x, y = int(cell[0]), int(cell[1])
    except (TypeError, ValueError, IndexError):
        raise ValueError(f"{what} must be an (x, y) pair of integers, got {cell!r}") from None
    if not (0 <= x < w and 0 <= y < h):
        raise ValueError(f"{what} {(x, y)} is outside the {w}x{h} map")
    return x, y


def _prep_costs(costs: np.ndarray | None, shape: tuple[int, int]) -> np.ndarray:
    if costs is None:
        return np.empty(0, dtype=np.float64)
    c = np.ascontiguousarray(costs, dtype=np.float64)
    if c.shape != shape:
        raise ValueError(f"costs shape {c.shape} does not match walls shape {shape}")
    if not np.all(c >= 1.0):  # also rejects NaN
        raise ValueError("cell costs must be >= 1")
    return c.reshape(-1)


class Planner:
    """A map prepared once for many queries.

    Safe to share between threads (queries on one planner run one at a time).
    ``find`` is optimal A*; ``reachable`` answers from connected components (O(1) once
    prepared); ``set_cell`` edits the map incrementally. With ``hierarchical=True``,
    ``find`` first searches a graph of portals between the regions of ``block``×``block``
    blocks and then runs exact A* restricted to the blocks of that route (near-optimal,
    much faster on big maps; see ``_hier``); ``find_optimal`` is always exact.
    """

    def __init__(self, walls: np.ndarray, costs: np.ndarray | None = None,
                 diagonal: bool = False, *, hierarchical: bool = False,
                 block: int | None = None) -> None:
        walls = np.asarray(walls)
        if walls.ndim != 2 or walls.size == 0:
            raise ValueError("walls must be a non-empty 2-D array indexed [y, x]")
        self.height, self.width = walls.shape
        self.diagonal = bool(diagonal)
        self.hierarchical = bool(hierarchical)
        # nonzero = blocked (as walls.astype(bool)), made in one pass without temporaries
        self._free = np.ascontiguousarray(walls == 0).view(np.uint8).reshape(-1)
        self._cost = _prep_costs(costs, walls.shape)
        self._hmul = self._min_cost()
        n = self.width * self.height
        # Work arrays reused by every query, mapped lazily (see _lazy_zeros): only the pages
        # a search touches are ever materialised.
        self._g = _lazy_zeros(n, np.float64)
        self._stamp = _lazy_zeros(n, np.int32)
        self._pdir = _lazy_zeros(n, np.int8)
        self._epoch = 0
        self._rev: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        # 8 directions, uniform cost: the jump point each jump point was reached from (_jps).
        self._parent: np.ndarray | None = None
        # Uniform cost, 4 directions: the bucket kernel's tiled work arrays (state, pdir)
        # forward and reverse, made on its first query.
        self._uni: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
        self._labels: np.ndarray | None = None
        self._alias: list[int] = []
        self._comp_dirty = False
        self._hier: Any = None
        self._block = block
        self._no_restrict = np.empty(0, dtype=np.uint8)
        # Queries share the work arrays: one query (or edit) at a time per planner.
        self._lock = threading.RLock()

    # -- preparation ---------------------------------------------------------------
    def _min_cost(self) -> float:
        if self._cost.shape[0] == 0:
            return 1.0
        free = self._free.astype(bool)
        return float(self._cost[free].min()) if free.any() else 1.0

    def prepare(self) -> Planner:
        """Build connected components (and the hierarchy in hierarchical mode) now rather
        than on the first query. Returns self."""
        with self._lock:
            self._components()
            if self.hierarchical:
                self._hierarchy()
            # Fault the work arrays in now so the first query does not pay for it.
            if self._uniform():
                arrays: tuple[np.ndarray, ...] = self._uni_arrays()
            elif self._jumps():
                arrays = (self._g, self._stamp, self._parent_array())
            else:
                arrays = (self._g, self._stamp, self._pdir, *self._reverse_arrays())
            for arr in arrays:
                arr.fill(0)
        return self

    def _components(self) -> np.ndarray:
        if self._labels is None or self._comp_dirty:
            size = max(self.width, self.height)
            labels, nlab = _k().label(self._free, self.width, self.height, size)
            self._labels = labels
            self._alias = list(range(nlab))
            self._comp_dirty = False
        return self._labels

    def _root(self, lab: int) -> int:
        alias = self._alias
        while alias[lab] != lab:
            alias[lab] = alias[alias[lab]]
            lab = alias[lab]
        return lab

    def _hierarchy(self) -> Any:
        if self._hier is None:
            from robo_comp.world._hier import Hierarchy

            self._hier = Hierarchy(self, self._block)
        return self._hier

    # -- queries -------------------------------------------------------------------
    def passable(self, x: int, y: int) -> bool:
        """True when (x, y) is inside the map and not a wall."""
        return 0 <= x < self.width and 0 <= y < self.height and bool(
            self._free[y * self.width + x])

    def reachable(self, a: Cell, b: Cell) -> bool:
        """Whether a path from ``a`` to ``b`` exists (both must be passable)."""
        with self._lock:
            return self._reachable(a, b)

    def _reachable(self, a: Cell, b: Cell) -> bool:
        ax, ay = _check_cell(a, self.width, self.height, "start")
        bx, by = _check_cell(b, self.width, self.height, "goal")
        if not (self.passable(ax, ay) and self.passable(bx, by)):
            return False
        labels = self._components()
        la = self._root(int(labels[ay * self.width + ax]))
        lb = self._root(int(labels[by * self.width + bx]))
        if la != lb:
            # Labels over-approximate connectivity (blocking never splits them), so a
            # difference is final even when cells were blocked since the last labelling.
            return False
        if self._comp_dirty:
            labels = self._components()
            return self._root(int(labels[ay * self.width + ax])) == self._root(
                int(labels[by * self.width + bx]))
        return True

    def _next_epoch(self) -> int:
        self._epoch += 1
        if self._epoch >= 2**30 - 1:
            self._stamp[:] = 0
            if self._rev is not None:
                self._rev[1][:] = 0
            if self._uni is not None:
                self._uni[0][:] = 0
                self._uni[2][:] = 0
            self._epoch = 1
        return self._epoch

    def _search(self, s: int, t: int, allow: np.ndarray, bsize: int, bw: int,
                first: int | None = None,
                probe: bool = False) -> tuple[float, int, list[Cell] | None]:
        """Exact A* s→t (within ``allow`` blocks); returns (cost or inf, expanded, path).

        With ``probe`` only the first, forward part runs: a search that has not finished
        within ``first`` expansions returns (-1, expanded, None) at once.

        Large plateaus of equal f (open areas, or walls the heuristic cannot see) make the
        expansion count depend heavily on the search direction, so when the forward search
        has not finished within a few times the straight-line distance, a reverse search
        joins it and the two take turns, each resuming where it stopped; the first to
        finish answers (both are exact). See ``_kernels.astar_both``.

        Unrestricted queries with 8 directions and cost 1 everywhere run on jump point search
        instead (``_jps``, exact too): it needs neither the probe nor the reverse search.
        """
        epoch = self._next_epoch()
        if first is None:
            first = 64 + 2 * (abs(s % self.width - t % self.width)
                              + abs(s // self.width - t // self.width))
        if self._uniform():
            return self._search_uniform(s, t, allow, bsize, bw, epoch, first, probe)
        if self._jumps() and allow.shape[0] == 0:
            return self._search_jumps(s, t, epoch)
        g2, stamp2, pdir2 = self._reverse_arrays()
        cost, expanded, rev = _k().astar_both(
            self._free, self._cost, self.width, self.height, s, t, self.diagonal,
            self._hmul, allow, bsize, bw, self._g, self._stamp, self._pdir,
            g2, stamp2, pdir2, epoch, first, probe)
        cost = float(cost)
        if rev == 2:
            return -1.0, int(expanded), None
        if math.isinf(cost):
            return cost, int(expanded), None
        if rev:
            path = self._path(t, s, pdir2)[::-1]
        else:
            path = self._path(s, t, self._pdir)
        return cost, int(expanded), path

    def _uniform(self) -> bool:
        """Whether queries run on the bucket kernel (cost 1 everywhere, 4 directions)."""
        return not self.diagonal and self._cost.shape[0] == 0

    def _uni_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        if self._uni is None:
            size = _k().tiled_size(self.width, self.height)[1]
            self._uni = (_lazy_zeros(size, np.int64), _lazy_zeros(size, np.int8),
                         _lazy_zeros(size, np.int64), _lazy_zeros(size, np.int8))
        return self._uni

    def _search_uniform(self, s: int, t: int, allow: np.ndarray, bsize: int, bw: int,
                        epoch: int, first: int,
                        probe: bool) -> tuple[float, int, list[Cell] | None]:
        state, pdir, state2, pdir2 = self._uni_arrays()
        cost, expanded, rev = _k().astar_uniform_both(
            self._free, self.width, self.height, s, t, allow, bsize, bw,
            state, pdir, state2, pdir2, epoch, first, probe)
        if rev == 2:
            return -1.0, int(expanded), None
        if cost < 0:
            return math.inf, int(expanded), None
        trace = _k().trace_tiled
        if rev:
            flat = trace(t, s, self.width, pdir2)[::-1]
        else:
            flat = trace(s, t, self.width, pdir)
        w = self.width
        return float(cost), int(expanded), list(zip((flat % w).tolist(), (flat // w).tolist()))

    def _search_jumps(self, s: int, t: int, epoch: int) -> tuple[float, int, list[Cell] | None]:
        """Jump point search (8 directions, uniform cost, no restriction): exact, and it
        expands so few cells that it needs no probe nor a reverse search (``_jps``)."""
        parent = self._parent_array()
        cost, expanded = _k().jps(self._free, self.width, self.height, s, t, self._g, self._stamp,
                                  parent, epoch)
        cost = float(cost)
        if math.isinf(cost):
            return cost, int(expanded), None
        flat = _k().trace_jumps(s, t, self.width, parent)
        w = self.width
        return cost, int(expanded), list(zip((flat % w).tolist(), (flat // w).tolist()))

    def _jumps(self) -> bool:
        """Whether unrestricted queries run on jump point search (8 directions, cost 1 everywhere)."""
        return self.diagonal and self._cost.shape[0] == 0

    def _parent_array(self) -> np.ndarray:
        if self._parent is None:
            self._parent = _lazy_zeros(self.width * self.height, np.int32)
        return self._parent

    def _reverse_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self._rev is None:
            n = self.width * self.height
            self._rev = (_lazy_zeros(n, np.float64), _lazy_zeros(n, np.int32),
                         _lazy_zeros(n, np.int8))
        return self._rev

    def _path(self, s: int, t: int, pdir: np.ndarray) -> list[Cell]:
        flat = _k().trace(s, t, self.width, pdir)
        w = self.width
        return list(zip((flat % w).tolist(), (flat // w).tolist()))

    def find_optimal(self, start: Cell, goal: Cell) -> PathResult:
        """Optimal path from ``start`` to ``goal`` (plain A* over the whole map)."""
        with self._lock:
            return self._find_optimal(start, goal)

    def _find_optimal(self, start: Cell, goal: Cell) -> PathResult:
        s, t = self._endpoints(start, goal)
        if s < 0:
            return PathResult(None, None, 0)
        if s == t:
            return PathResult([start_xy(s, self.width)], 0.0, 0)
        cost, expanded, path = self._search(s, t, self._no_restrict, 1, 1)
        if path is None:
            return PathResult(None, None, expanded)
        return PathResult(path, cost, expanded)

    def find(self, start: Cell, goal: Cell) -> PathResult:
        """Path from ``start`` to ``goal``: optimal, or near-optimal in hierarchical mode.

        Returns a :class:`PathResult` whose path is None when start or goal is a wall or no
        path exists ("no path" is answered from connected components without a search).
        """
        if not self.hierarchical:
            return self.find_optimal(start, goal)
        with self._lock:
            s, t = self._endpoints(start, goal)
            if s < 0:
                return PathResult(None, None, 0)
            if s == t:
                return PathResult([start_xy(s, self.width)], 0.0, 0)
            return self._hierarchy().find(s, t)

    def _endpoints(self, start: Cell, goal: Cell) -> tuple[int, int]:
        """Flat (s, t), or (-1, -1) when no path can exist."""
        sx, sy = _check_cell(start, self.width, self.height, "start")
        gx, gy = _check_cell(goal, self.width, self.height, "goal")
        if not self._reachable((sx, sy), (gx, gy)):
            return -1, -1
        return sy * self.width + sx, gy * self.width + gx

    # -- edits ---------------------------------------------------------------------
    def set_cell(self, x: int, y: int, blocked: bool, cost: float | None = None) -> None:
        """Block or free cell (x, y), optionally changing its cost, without a full rebuild.

        Freeing merges the neighbouring components at once (union-find over labels);
        blocking marks components stale and they are relabelled lazily only when a
        "same component" answer needs confirming. The hierarchy is rebuilt lazily.
        """
        with self._lock:
            self._set_cell(x, y, blocked, cost)

    def _set_cell(self, x: int, y: int, blocked: bool, cost: float | None) -> None:
        x, y = _check_cell((x, y), self.width, self.height, "cell")
        v = y * self.width + x
        if cost is not None:
            if not cost >= 1.0:
                raise ValueError("cell costs must be >= 1")
            if self._cost.shape[0] == 0:
                self._cost = np.ones(self.width * self.height, dtype=np.float64)
            self._cost[v] = float(cost)
            self._hmul = min(self._hmul, float(cost)) if not blocked else self._hmul
        was_free = bool(self._free[v])
        self._free[v] = 0 if blocked else 1
        if self._hier is not None:
            self._hier = None
        if self._labels is None or was_free == (not blocked):
            return
        if blocked:
            self._comp_dirty = True
            self._labels[v] = -1
            return
        roots = set()
        for nx, ny in ((x + 1, y), (x - 1, y), (x, y + 1), (x, y - 1)):
            if 0 <= nx < self.width and 0 <= ny < self.height:
                lab = int(self._labels[ny * self.width + nx])
                if lab >= 0:
                    roots.add(self._root(lab))
        if roots:
            keep = min(roots)
            for r in roots:
                self._alias[r] = keep
            self._labels[v] = keep
        else:
            self._alias.append(len(self._alias))
            self._labels[v] = len(self._alias) - 1


def start_xy(v: int, w: int) -> Cell:
    """(x, y) of flat cell index ``v`` in a map of width ``w``."""
    return (v % w, v // w)


def find_path(walls: np.ndarray, start: Cell, goal: Cell, *, diagonal: bool = False,
              costs: np.ndarray | None = None) -> list[Cell] | None:
    """Optimal path from ``start`` to ``goal`` as (x, y) cells, both inclusive.

    ``walls`` is a bool array indexed [y, x] (True = blocked). Returns None when there is
    no path (or an endpoint is a wall); ``[start]`` when start == goal. Raises ValueError
    for endpoints outside the map. For many queries on one map, build a :class:`Planner`.
    """
    walls = np.asarray(walls, dtype=bool)
    h, w = walls.shape
    sx, sy = _check_cell(start, w, h, "start")
    gx, gy = _check_cell(goal, w, h, "goal")
    if walls[sy, sx] or walls[gy, gx]:
        return None
    if (sx, sy) == (gx, gy):
        return [(sx, sy)]
    # One-off query: no component labelling of the whole map. A short search answers
    # most queries; when it has not, a flood fill from the start (stopping at the goal)
    # answers "no path" before the full search would exhaust the start's component.
    p = Planner(walls, costs=costs, diagonal=diagonal)
    s, t = sy * w + sx, gy * w + gx
    cost, _, path = p._search(s, t, p._no_restrict, 1, 1, probe=True)
    if cost >= 0:
        return path
    if not _k().connected(p._free, w, h, s, t):  # marks p._free (private to this query)
        return None
    return p._search(s, t, p._no_restrict, 1, 1)[2]

"""Planner: optimality against a brute-force Dijkstra, semantics, components, edits,
hierarchical mode."""
from __future__ import annotations

import heapq
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robo_comp.world import planner as pl
from robo_comp.world.maps import thesis_map
from robo_comp.world.planner import Planner, find_path, obstacle_costs

SQ2 = math.sqrt(2)


def moves(walls, x, y, diagonal):
    """Legal moves from (x, y): (nx, ny, step length); no corner cutting."""
    h, w = walls.shape
    dirs = [(1, 0), (0, 1), (-1, 0), (0, -1)]
    if diagonal:
        dirs += [(1, 1), (-1, 1), (-1, -1), (1, -1)]
    for dx, dy in dirs:
        nx, ny = x + dx, y + dy
        if not (0 <= nx < w and 0 <= ny < h) or walls[ny, nx]:
            continue
        if dx and dy and (walls[y, nx] or walls[ny, x]):
            continue
        yield nx, ny, (SQ2 if dx and dy else 1.0)


def dijkstra(walls, costs, start, goal, diagonal):
    dist = {start: 0.0}
    heap = [(0.0, start)]
    while heap:
        d, (x, y) = heapq.heappop(heap)
        if (x, y) == goal:
            return d
        if d > dist[(x, y)]:
            continue
        for nx, ny, step in moves(walls, x, y, diagonal):
            nd = d + step * (1.0 if costs is None else costs[ny, nx])
            if nd < dist.get((nx, ny), math.inf) - 1e-12:
                dist[(nx, ny)] = nd
                heapq.heappush(heap, (nd, (nx, ny)))
    return None


def path_cost(walls, costs, path, diagonal):
    total = 0.0
    for (x, y), (nx, ny) in zip(path, path[1:]):
        legal = {(a, b): s for a, b, s in moves(walls, x, y, diagonal)}
        assert (nx, ny) in legal, f"illegal step {(x, y)}->{(nx, ny)}"
        total += legal[(nx, ny)] * (1.0 if costs is None else costs[ny, nx])
    return total


@st.composite
def problems(draw):
    w = draw(st.integers(1, 9))
    h = draw(st.integers(1, 9))
    density = draw(st.sampled_from([0.0, 0.2, 0.35, 0.5]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    walls = rng.random((h, w)) < density
    costs = None
    if draw(st.booleans()):
        costs = rng.choice([1.0, 1.0, 2.5, 10.0], size=(h, w))
    start = (draw(st.integers(0, w - 1)), draw(st.integers(0, h - 1)))
    goal = (draw(st.integers(0, w - 1)), draw(st.integers(0, h - 1)))
    walls[start[1], start[0]] = False
    walls[goal[1], goal[0]] = False
    return walls, costs, start, goal, draw(st.booleans())


@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(problems())
def test_optimal_against_dijkstra(prob):
    walls, costs, start, goal, diagonal = prob
    want = dijkstra(walls, costs, start, goal, diagonal)
    p = Planner(walls, costs=costs, diagonal=diagonal)
    res = p.find(start, goal)
    fp = find_path(walls, start, goal, diagonal=diagonal, costs=costs)
    if want is None:
        assert res.path is None and res.cost is None and fp is None
        assert not p.reachable(start, goal)
        return
    assert p.reachable(start, goal)
    assert res.cost == pytest.approx(want, rel=1e-9)
    assert res.path[0] == start and res.path[-1] == goal
    assert path_cost(walls, costs, res.path, diagonal) == pytest.approx(want, rel=1e-9)
    assert fp[0] == start and fp[-1] == goal
    assert path_cost(walls, costs, fp, diagonal) == pytest.approx(want, rel=1e-9)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(problems(), st.integers(1, 40))
def test_forward_reverse_turns_stay_optimal(prob, first):
    """Tiny first budgets force the forward and reverse searches to take (resumed) turns."""
    walls, costs, start, goal, diagonal = prob
    want = dijkstra(walls, costs, start, goal, diagonal)
    p = Planner(walls, costs=costs, diagonal=diagonal)
    w = walls.shape[1]
    cost, _, path = p._search(start[1] * w + start[0], goal[1] * w + goal[0],
                              p._no_restrict, 1, 1, first=first)
    if want is None:
        assert path is None
        return
    assert cost == pytest.approx(want, rel=1e-9)
    assert path[0] == start and path[-1] == goal
    assert path_cost(walls, costs, path, diagonal) == pytest.approx(want, rel=1e-9)


@pytest.mark.parametrize("kind", [3, 4, 5])
def test_plateau_maps_optimal(kind):
    m = thesis_map(kind, 64)
    for diagonal in (False, True):
        want = dijkstra(m.walls, None, (0, 0), (63, 63), diagonal)
        got = Planner(m.walls, diagonal=diagonal).find((0, 0), (63, 63))
        assert got.cost == pytest.approx(want)


def test_find_path_basics():
    walls = np.zeros((5, 5), dtype=bool)
    walls[2, 0:4] = True
    assert find_path(walls, (1, 1), (1, 1)) == [(1, 1)]
    path = find_path(walls, (0, 0), (0, 4))
    assert path[0] == (0, 0) and path[-1] == (0, 4) and len(path) == 13
    walls[2, 4] = True
    assert find_path(walls, (0, 0), (0, 4)) is None
    assert find_path(walls, (0, 2), (0, 4)) is None  # start on a wall
    with pytest.raises(ValueError):
        find_path(walls, (5, 0), (0, 0))


def test_no_corner_cutting():
    walls = np.array([[False, True], [False, False]])
    # (0,0)->(1,1) diagonally would cut the corner of the wall at (1,0)
    assert find_path(walls, (0, 0), (1, 1), diagonal=True) == [(0, 0), (0, 1), (1, 1)]
    walls = np.array([[False, True], [True, False]])
    assert find_path(walls, (0, 0), (1, 1), diagonal=True) is None


def test_costs_steer_path_and_obstacle_costs():
    walls = np.zeros((3, 5), dtype=bool)
    walls[1, 2] = True
    c = obstacle_costs(walls, near_cost=10.0)
    assert c[0, 1] == 10.0 and c[0, 0] == 1.0 and c[1, 2] == 1.0 and c.shape == walls.shape
    costs = np.ones((3, 5))
    costs[0, 1:4] = 50.0
    res = Planner(walls, costs=costs).find((0, 0), (4, 0))
    assert (2, 2) in res.path and res.cost == pytest.approx(8.0)


def test_no_path_answered_by_components_fast():
    m = thesis_map(2, 400)
    p = Planner(m.walls).prepare()
    p.find((0, 0), (0, 1))
    res = p.find((0, 0), (399, 399))
    # answered by the component labels, no cell expanded (the time is bench_planner's figure)
    assert res.path is None and res.expanded == 0


def test_set_cell_updates_components_and_paths():
    walls = np.zeros((5, 5), dtype=bool)
    walls[:, 2] = True
    walls[2, 2] = False
    p = Planner(walls).prepare()
    assert p.reachable((0, 0), (4, 4))
    p.set_cell(2, 2, blocked=True)
    assert not p.reachable((0, 0), (4, 4))
    assert p.find((0, 0), (4, 4)).path is None
    p.set_cell(2, 4, blocked=False)
    assert p.reachable((0, 0), (4, 4))
    res = p.find((0, 0), (4, 4))
    assert (2, 4) in res.path and res.cost == 8
    p.set_cell(1, 4, blocked=False, cost=5.0)  # already free: cost change only
    assert p.find((0, 0), (4, 4)).cost == pytest.approx(12.0)
    p.set_cell(0, 0, blocked=True)
    assert p.find((0, 0), (4, 4)).path is None


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_set_cell_random_edits_stay_correct(seed):
    rng = np.random.default_rng(seed)
    walls = rng.random((8, 8)) < 0.4
    p = Planner(walls).prepare()
    for _ in range(12):
        x, y = map(int, rng.integers(0, 8, 2))
        blocked = bool(rng.random() < 0.5)
        p.set_cell(x, y, blocked)
        walls[y, x] = blocked
        a = tuple(map(int, rng.integers(0, 8, 2)))
        b = tuple(map(int, rng.integers(0, 8, 2)))
        if walls[a[1], a[0]] or walls[b[1], b[0]]:
            continue
        want = dijkstra(walls, None, a, b, False)
        assert p.reachable(a, b) == (want is not None)
        got = p.find(a, b).cost
        assert (got is None) == (want is None)
        if want is not None:
            assert got == pytest.approx(want)


@pytest.mark.parametrize("kind", [1, 2, 3, 4, 5])
@pytest.mark.parametrize("diagonal", [False, True])
def test_hierarchical_thesis_maps_within_2_percent(kind, diagonal):
    n = 300
    m = thesis_map(kind, n)
    opt = Planner(m.walls, diagonal=diagonal).find((0, 0), (n - 1, n - 1))
    hier = Planner(m.walls, diagonal=diagonal, hierarchical=True, block=16)
    res = hier.find((0, 0), (n - 1, n - 1))
    if opt.cost is None:
        assert res.path is None
        return
    assert res.cost <= opt.cost * 1.02
    assert path_cost(m.walls, None, res.path, diagonal) == pytest.approx(res.cost)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_hierarchical_random_maps_valid(seed, diagonal):
    rng = np.random.default_rng(seed)
    walls = rng.random((40, 50)) < 0.3
    walls[0, 0] = walls[39, 49] = False
    hier = Planner(walls, diagonal=diagonal, hierarchical=True, block=5)
    want = dijkstra(walls, None, (0, 0), (49, 39), diagonal)
    res = hier.find((0, 0), (49, 39))
    assert (res.path is None) == (want is None)
    if want is not None:
        assert res.cost >= want - 1e-9
        assert path_cost(walls, None, res.path, diagonal) == pytest.approx(res.cost)


def test_hierarchical_fallback(monkeypatch):
    from robo_comp.world import _hier

    m = thesis_map(5, 200)
    hier = Planner(m.walls, hierarchical=True, block=10)
    monkeypatch.setattr(_hier.Hierarchy, "corridor", lambda self, s, t, margin=1: None)
    res = hier.find((0, 0), (199, 199))
    assert res.cost == 398
    # a corridor that cannot hold the path: the restricted search fails, the full one runs
    monkeypatch.setattr(_hier.Hierarchy, "corridor",
                        lambda self, s, t, margin=1: np.zeros(self.bh * self.bw, np.uint8))
    assert hier.find((0, 0), (199, 199)).cost == 398


def test_hierarchical_any_size_and_edits():
    walls = np.zeros((37, 53), dtype=bool)  # not a multiple of the block
    walls[10, :50] = True
    p = Planner(walls, hierarchical=True, block=7)
    res = p.find((0, 0), (52, 36))
    assert res.cost == pytest.approx(Planner(walls).find((0, 0), (52, 36)).cost)
    p.set_cell(50, 10, blocked=True)
    p.set_cell(51, 10, blocked=True)
    p.set_cell(52, 10, blocked=True)
    assert p.find((0, 0), (52, 36)).path is None
    p.set_cell(3, 10, blocked=False)
    res = p.find((0, 0), (52, 36))
    assert res.path is not None and (3, 10) in res.path


def test_bad_inputs():
    with pytest.raises(ValueError):
        Planner(np.zeros((0, 3), dtype=bool))
    with pytest.raises(ValueError):
        Planner(np.zeros((3, 3), dtype=bool), costs=np.zeros((3, 3)))
    with pytest.raises(ValueError):
        Planner(np.zeros((3, 3), dtype=bool)).find((0, 0), (3, 0))


def test_import_is_lazy():
    import subprocess
    import sys

    code = ("import sys, robo_comp.world.planner, robo_comp.world.paths as p; "
            "print('numba' in sys.modules, p._kernels is None)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "True"]
    assert pl.warm_up() >= 0.0


def bfs_all(walls, start):
    """Steps from ``start`` to every cell over 4-connected free cells (-1: unreachable)."""
    h, w = walls.shape
    dist = np.full((h, w), -1, dtype=np.int64)
    dist[start[1], start[0]] = 0
    front = [start]
    while front:
        nxt = []
        for x, y in front:
            for nx, ny, _ in moves(walls, x, y, False):
                if dist[ny, nx] < 0:
                    dist[ny, nx] = dist[y, x] + 1
                    nxt.append((nx, ny))
        front = nxt
    return dist


def _free_cells(walls, rng, k):
    ys, xs = np.nonzero(~walls)
    pick = rng.choice(len(xs), size=min(k, len(xs)), replace=False)
    return [(int(xs[i]), int(ys[i])) for i in pick]


@pytest.mark.parametrize("seed", range(4))
def test_uniform_kernel_optimal_on_tiled_maps(seed):
    """Cost 1 and 4 directions run on the bucket-queue kernel with 32×32-tiled work arrays:
    maps larger than a tile and not multiples of it, many queries on one prepared planner
    (earlier queries' marks left in the arrays) and one-off ``find_path``, against BFS."""
    rng = np.random.default_rng(seed)
    h, w = 70 + 13 * seed, 45 + 29 * seed
    walls = rng.random((h, w)) < [0.0, 0.25, 0.4, 0.3][seed]
    p = Planner(walls)
    if seed % 2:
        p.prepare()
    for start in _free_cells(walls, rng, 12):
        dist = bfs_all(walls, start)
        for goal in _free_cells(walls, rng, 8):
            want = int(dist[goal[1], goal[0]])
            res = p.find(start, goal)
            fp = find_path(walls, start, goal)
            if want < 0:
                assert res.path is None and fp is None
                continue
            assert res.cost == want
            assert res.path[0] == start and res.path[-1] == goal
            assert path_cost(walls, None, res.path, False) == want
            assert fp[0] == start and fp[-1] == goal and path_cost(walls, None, fp, False) == want


def test_uniform_kernel_marks_wrap_around():
    """The epoch counter wrapping resets the tiled work arrays too (no stale 'closed')."""
    m = thesis_map(5, 80)
    p = Planner(m.walls)
    p._epoch = 2**30 - 4
    for _ in range(6):
        assert p.find((0, 0), (79, 79)).cost == 158
        assert p.find((79, 79), (0, 0)).cost == 158


def test_one_shot_no_path_answered_by_flood_fill(monkeypatch):
    """A one-off ``find_path`` whose short first search does not finish asks a flood fill
    from the start before searching on: "no path" comes from the fill, without the
    exhaustive search; with a path the full search still returns an optimal one. (An
    8-connected query on a uniform map runs jump point search, which needs no fill.)"""
    k = pl._k()
    real_fill = k.connected
    fills: list[bool] = []
    searches: list[bool] = []
    real_search = Planner._search

    def fill(*a):
        fills.append(bool(real_fill(*a)))
        return fills[-1]

    def search(self, *a, **kw):
        searches.append(bool(kw.get("probe", False)))
        return real_search(self, *a, **kw)

    monkeypatch.setattr(k, "connected", fill)
    monkeypatch.setattr(Planner, "_search", search)
    n = 300  # the first search's budget (64 + 2 * 598 expansions) is far below the start's component
    assert find_path(thesis_map(2, n).walls, (0, 0), (n - 1, n - 1)) is None
    assert fills == [False] and searches == [True]
    fills.clear()
    searches.clear()
    walls = thesis_map(5, n).walls
    path = find_path(walls, (0, 0), (n - 1, n - 1))
    assert fills == [True] and searches == [True, False]
    assert path_cost(walls, None, path, False) == 2 * (n - 1)
    fills.clear()
    searches.clear()
    walls = np.zeros((n, n), dtype=bool)
    walls[:, n // 2] = True  # a wall from top to bottom: the fill must exhaust the left half
    assert find_path(walls, (0, 0), (n - 1, 0)) is None
    path = find_path(walls, (0, 0), (n // 2 - 1, n - 1), diagonal=True)
    assert path_cost(walls, None, path, True) == pytest.approx((n // 2 - 1) * SQ2 + n // 2)
    # 8 directions on a uniform map: jump point search answers in its first search, no fill
    assert fills == [False] and searches == [True, True]


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(1, 40), st.integers(1, 40), st.sampled_from([0.0, 0.3, 0.45, 0.6]),
       st.integers(0, 2**32 - 1))
def test_flood_fill_agrees_with_labels(w, h, density, seed):
    """The one-off query's flood fill (``connected``) against the component labels."""
    rng = np.random.default_rng(seed)
    walls = rng.random((h, w)) < density
    free = np.ascontiguousarray(~walls, dtype=np.uint8).reshape(-1)
    labels, _ = pl._k().label(free, w, h, max(w, h))
    cells = np.flatnonzero(free)
    if len(cells) == 0:
        return
    for _ in range(10):
        s, t = (int(c) for c in rng.choice(cells, size=2))
        assert pl._k().connected(free.copy(), w, h, s, t) == (labels[s] == labels[t])


def test_flood_fill_grows_its_stack():
    """Free rows between rows of one-cell gaps leave ~w/2 pending runs per row pair: the
    fill outgrows its first stack, grows it and still answers right."""
    h, w = 400, 401
    walls = np.zeros((h, w), dtype=bool)
    walls[1::2, 1::2] = True
    free = np.ascontiguousarray(~walls, dtype=np.uint8).reshape(-1)
    k = pl._k()
    sx = np.zeros(4 * w + 64, dtype=np.int32)
    sy = np.zeros(4 * w + 64, dtype=np.int32)
    assert k._fill_spans(free.copy(), w, h, w * h - 1, sx, sy, 1)[0] == 2  # the first stack is too small
    assert k.connected(free.copy(), w, h, 0, w * h - 1)
    walls[h // 2, :] = True
    free = np.ascontiguousarray(~walls, dtype=np.uint8).reshape(-1)
    marked = free.copy()
    assert not k.connected(marked, w, h, 0, w * h - 1)
    # the fill marked (2) the whole upper part it exhausted, and nothing below the wall
    assert (marked[: (h // 2) * w] != 1).all() and (marked[(h // 2) * w:] != 2).all()
    assert k.connected(free, w, h, 0, (h // 2 - 1) * w + w - 1)

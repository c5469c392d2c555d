"""Compiled (numba) jump point search: 8-connected queries on uniform-cost maps.

Private module, imported lazily by :mod:`robo_comp.world.planner` (like ``_kernels``). It
answers the same queries as the A* kernel when every step costs 1 (√2 diagonally) and a
diagonal step needs both orthogonal neighbours free (no corner cutting, the Moving AI
convention), and gives the same optimal cost: it expands only *jump points*, the cells where
an optimal path may have to turn (Harabor and Grastien, "Online graph pruning for
pathfinding on grid maps", AAAI 2011; the rules without corner cutting from their "Improving
jump point search", ICAPS 2014):

* a straight run stops at a cell with a *forced* neighbour: a free cell beside it whose
  neighbour behind (beside the previous cell) is blocked, so that only this cell reaches it;
* a diagonal run stops at a cell from which a straight run (along either of its two
  components) stops somewhere; diagonal runs have no forced neighbours without corner
  cutting;
* both stop at the goal.

From a jump point reached straight, the search goes on straight and to its forced
neighbours (and the diagonal between); from one reached diagonally, along the diagonal and
its two components. Between two jump points the path is a straight or diagonal line, so a
step's cost is exact and the path is the lines filled in. Cells are flat ``v = y * w + x``.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from robo_comp.world._heap import grow as _grow
from robo_comp.world._heap import pop as _heap_pop
from robo_comp.world._heap import push as _heap_push

SQRT2 = 1.4142135623730951


@njit(cache=True, inline="always", nogil=True)
def _ok(free, w, h, x, y):
    return x >= 0 and y >= 0 and x < w and y < h and free[y * w + x] != 0


@njit(cache=True, nogil=True)
def _run_x(free, w, h, x, y, dx, tx, ty):
    """Run from (x, y) along x by ``dx``; the jump point it stops at, or -1."""
    while True:
        if not _ok(free, w, h, x, y):
            return -1
        if x == tx and y == ty:
            return y * w + x
        if (_ok(free, w, h, x, y - 1) and not _ok(free, w, h, x - dx, y - 1)) or \
                (_ok(free, w, h, x, y + 1) and not _ok(free, w, h, x - dx, y + 1)):
            return y * w + x
        x += dx


@njit(cache=True, nogil=True)
def _run_y(free, w, h, x, y, dy, tx, ty):
    """Run from (x, y) along y by ``dy``; the jump point it stops at, or -1."""
    while True:
        if not _ok(free, w, h, x, y):
            return -1
        if x == tx and y == ty:
            return y * w + x
        if (_ok(free, w, h, x - 1, y) and not _ok(free, w, h, x - 1, y - dy)) or \
                (_ok(free, w, h, x + 1, y) and not _ok(free, w, h, x + 1, y - dy)):
            return y * w + x
        y += dy


@njit(cache=True, nogil=True)
def _run_diag(free, w, h, x, y, dx, dy, tx, ty):
    """Run diagonally from (x, y) (a free cell the step into was legal); its jump point, or -1."""
    while True:
        if x == tx and y == ty:
            return y * w + x
        if _run_x(free, w, h, x + dx, y, dx, tx, ty) >= 0 or _run_y(free, w, h, x, y + dy, dy, tx, ty) >= 0:
            return y * w + x
        if _ok(free, w, h, x + dx, y) and _ok(free, w, h, x, y + dy) and _ok(free, w, h, x + dx, y + dy):
            x += dx
            y += dy
        else:
            return -1


@njit(cache=True, inline="always", nogil=True)
def _octile(ax, ay, bx, by):
    dx = abs(ax - bx)
    dy = abs(ay - by)
    if dx < dy:
        return dy + (SQRT2 - 1.0) * dx
    return dx + (SQRT2 - 1.0) * dy


@njit(cache=True, nogil=True)
def _sign(a):
    return (a > 0) - (a < 0)


@njit(cache=True, nogil=True)
def jps(free, w, h, s, t, g, stamp, parent, epoch):
    """Optimal 8-connected uniform-cost path cost s → t (inf when none) and the jump points
    expanded. ``g``/``stamp``/``parent`` are the caller's work arrays (``stamp[v] ==
    2*epoch`` open, ``2*epoch+1`` closed); ``parent[v]`` is the jump point v was reached from
    (see :func:`trace`)."""
    hf = np.empty(1024, dtype=np.float64)
    hh = np.empty(1024, dtype=np.float64)
    hv = np.empty(1024, dtype=np.int64)
    seq = np.int64(1) << 30
    g[s] = 0.0
    stamp[s] = 2 * epoch
    parent[s] = s
    h0 = _octile(s % w, s // w, t % w, t // w)
    size = _heap_push(hf, hh, hv, 0, h0, h0, (seq << 32) | s)
    expanded = 0
    while True:
        done, cost, size, seq, expanded = _search(free, w, h, s, t, g, stamp, parent, epoch,
                                                  hf, hh, hv, size, seq, expanded)
        if done:
            return cost, expanded
        hf = _grow(hf, size)
        hh = _grow(hh, size)
        hv = _grow(hv, size)


@njit(cache=True, nogil=True)
def _search(free, w, h, s, t, g, stamp, parent, epoch, hf, hh, hv, size, seq, expanded):
    """The search loop of :func:`jps`, resumable: (True, cost, ...) when done, (False, ...)
    when the heap may not hold the next expansion's successors (grow it and call again). It
    never rebinds its arrays (in numba that would cost more than the search)."""
    open_mark = 2 * epoch
    closed_mark = open_mark + 1
    tx = t % w
    ty = t // w
    cap = hf.shape[0]
    succ = np.empty(8, dtype=np.int64)
    while size > 0:
        if size + 8 > cap:
            return False, 0.0, size, seq, expanded
        v = hv[0] & 0xFFFFFFFF
        size = _heap_pop(hf, hh, hv, size)
        if stamp[v] == closed_mark:
            continue  # stale duplicate
        stamp[v] = closed_mark
        expanded += 1
        gv = g[v]
        if v == t:
            return True, gv, size, seq, expanded
        y = v // w
        x = v - y * w
        n = 0
        if v == s:
            for dx in (-1, 0, 1):
                for dy in (-1, 0, 1):
                    if dx == 0 and dy == 0:
                        continue
                    if dx == 0:
                        j = _run_y(free, w, h, x, y + dy, dy, tx, ty)
                    elif dy == 0:
                        j = _run_x(free, w, h, x + dx, y, dx, tx, ty)
                    elif _ok(free, w, h, x + dx, y) and _ok(free, w, h, x, y + dy) and _ok(free, w, h, x + dx, y + dy):
                        j = _run_diag(free, w, h, x + dx, y + dy, dx, dy, tx, ty)
                    else:
                        j = -1
                    if j >= 0:
                        succ[n] = j
                        n += 1
        else:
            p = parent[v]
            dx = _sign(x - p % w)
            dy = _sign(y - p // w)
            if dx != 0 and dy != 0:  # reached diagonally: the two components and the diagonal
                j = _run_x(free, w, h, x + dx, y, dx, tx, ty)
                if j >= 0:
                    succ[n] = j
                    n += 1
                j = _run_y(free, w, h, x, y + dy, dy, tx, ty)
                if j >= 0:
                    succ[n] = j
                    n += 1
                if _ok(free, w, h, x + dx, y) and _ok(free, w, h, x, y + dy) and _ok(free, w, h, x + dx, y + dy):
                    j = _run_diag(free, w, h, x + dx, y + dy, dx, dy, tx, ty)
                    if j >= 0:
                        succ[n] = j
                        n += 1
            elif dx != 0:  # along x: on, and to each forced side (and the diagonal there)
                ahead = _ok(free, w, h, x + dx, y)
                if ahead:
                    j = _run_x(free, w, h, x + dx, y, dx, tx, ty)
                    if j >= 0:
                        succ[n] = j
                        n += 1
                for sy in (-1, 1):
                    if _ok(free, w, h, x, y + sy) and not _ok(free, w, h, x - dx, y + sy):
                        j = _run_y(free, w, h, x, y + sy, sy, tx, ty)
                        if j >= 0:
                            succ[n] = j
                            n += 1
                        if ahead and _ok(free, w, h, x + dx, y + sy):
                            j = _run_diag(free, w, h, x + dx, y + sy, dx, sy, tx, ty)
                            if j >= 0:
                                succ[n] = j
                                n += 1
            else:  # along y
                ahead = _ok(free, w, h, x, y + dy)
                if ahead:
                    j = _run_y(free, w, h, x, y + dy, dy, tx, ty)
                    if j >= 0:
                        succ[n] = j
                        n += 1
                for sx in (-1, 1):
                    if _ok(free, w, h, x + sx, y) and not _ok(free, w, h, x + sx, y - dy):
                        j = _run_x(free, w, h, x + sx, y, sx, tx, ty)
                        if j >= 0:
                            succ[n] = j
                            n += 1
                        if ahead and _ok(free, w, h, x + sx, y + dy):
                            j = _run_diag(free, w, h, x + sx, y + dy, sx, dy, tx, ty)
                            if j >= 0:
                                succ[n] = j
                                n += 1
        for i in range(n):
            u = succ[i]
            su = stamp[u]
            if su == closed_mark:
                continue
            ux = u % w
            uy = u // w
            ng = gv + _octile(x, y, ux, uy)
            if su == open_mark and ng >= g[u]:
                continue
            g[u] = ng
            stamp[u] = open_mark
            parent[u] = v
            hu = _octile(ux, uy, tx, ty)
            seq -= 1
            size = _heap_push(hf, hh, hv, size, ng + hu, hu, (seq << 32) | u)
    return True, np.inf, size, seq, expanded


@njit(cache=True, nogil=True)
def trace(s, t, w, parent):
    """The cells s → t (flat, both included): the lines between the jump points filled in."""
    n = 1
    v = t
    while v != s:
        p = parent[v]
        n += max(abs(v % w - p % w), abs(v // w - p // w))
        v = p
    out = np.empty(n, dtype=np.int64)
    i = n - 1
    v = t
    out[i] = t
    while v != s:
        p = parent[v]
        dx = _sign(p % w - v % w)
        dy = _sign(p // w - v // w)
        c = v
        while c != p:
            c += dy * w + dx
            i -= 1
            out[i] = c
        v = p
    return out

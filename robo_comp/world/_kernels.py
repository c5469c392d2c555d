"""Compiled (numba) kernels of the planner: A* over flat cell indices and grid labelling.

Private module: :mod:`robo_comp.world.planner` imports it lazily so that importing the
planner does not pay for numba. Cells are flat indices ``v = y * w + x``.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from robo_comp.world._heap import grow as _grow
from robo_comp.world._heap import pop as _heap_pop
from robo_comp.world._heap import push as _heap_push

SQRT2 = 1.4142135623730951

# Direction tables: 0..3 orthogonal (E, S, W, N), 4..7 diagonal (SE, SW, NW, NE).
DX = np.array([1, 0, -1, 0, 1, -1, -1, 1], dtype=np.int64)
DY = np.array([0, 1, 0, -1, 1, 1, -1, -1], dtype=np.int64)
# For diagonal d (index d-4) the two orthogonal directions that must be free.
DIAG_A = np.array([0, 2, 2, 0], dtype=np.int64)
DIAG_B = np.array([1, 1, 3, 3], dtype=np.int64)


@njit(cache=True, nogil=True)
def _heuristic(x, y, tx, ty, diagonal, hmul):
    dx = abs(x - tx)
    dy = abs(y - ty)
    if diagonal:
        if dx < dy:
            return hmul * (dy + (SQRT2 - 1.0) * dx)
        return hmul * (dx + (SQRT2 - 1.0) * dy)
    return hmul * (dx + dy)


@njit(cache=True, nogil=True)
def _astar_core(free, cost, w, h, t, diagonal, hmul, allow, bsize, bw, g, stamp, epoch, pdir,
                reverse, budget, hf, hh, hv, size, seq, expanded):
    """The A* loop, resumable: expands from the heap ``hf``/``hh``/``hv`` (``size`` entries)
    towards ``t`` and returns (status, cost, size, seq, expanded) with status 0 done (cost,
    or inf when there is no path), 1 heap full (grow it and call again), 2 ``budget`` (> 0)
    expansions reached. Never rebinds its arrays: in numba, rebinding array variables
    inside a hot loop costs several times the search itself.

    ``free`` uint8 per cell (1 = passable); ``cost`` float64 per cell or empty for uniform
    1; ``allow`` uint8 per block of ``bsize`` cells (``bw`` blocks a row) or empty for no
    restriction. ``g``/``stamp``/``pdir`` are caller-owned work arrays reused across
    queries: ``stamp[v] == 2*epoch`` marks v open with a valid ``g``, ``2*epoch+1``
    closed; ``pdir[v]`` is the direction that led into v (see :func:`trace`). With
    ``reverse`` the search runs from the goal side and a step u→v costs what the forward
    step v→u costs (the cost of cell u).
    """
    use_cost = cost.shape[0] > 0
    restrict = allow.shape[0] > 0
    open_mark = 2 * epoch
    closed_mark = open_mark + 1
    tx = t % w
    ty = t // w
    cap = hf.shape[0]
    ndir = 8 if diagonal else 4
    while size > 0:
        if size + 8 > cap:
            return 1, 0.0, size, seq, expanded
        if budget > 0 and expanded >= budget:
            # checked before popping, so a resumed search loses nothing
            return 2, -1.0, size, seq, expanded
        v = hv[0] & 0xFFFFFFFF
        size = _heap_pop(hf, hh, hv, size)
        if stamp[v] == closed_mark:
            continue  # stale duplicate
        gv = g[v]
        stamp[v] = closed_mark
        expanded += 1
        if v == t:
            return 0, gv, size, seq, expanded
        y = v // w
        x = v - y * w
        for d in range(ndir):
            nx = x + DX[d]
            ny = y + DY[d]
            if nx < 0 or ny < 0 or nx >= w or ny >= h:
                continue
            u = ny * w + nx
            if free[u] == 0:
                continue
            if d >= 4:
                a = DIAG_A[d - 4]
                b = DIAG_B[d - 4]
                if free[(y + DY[a]) * w + x + DX[a]] == 0 or free[(y + DY[b]) * w + x + DX[b]] == 0:
                    continue
            if restrict and allow[(ny // bsize) * bw + nx // bsize] == 0:
                continue
            su = stamp[u]
            if su == closed_mark:
                continue
            step = SQRT2 if d >= 4 else 1.0
            if use_cost:
                step *= cost[v] if reverse else cost[u]
            ng = gv + step
            if su == open_mark and ng >= g[u]:
                continue
            g[u] = ng
            stamp[u] = open_mark
            pdir[u] = d
            hu = _heuristic(nx, ny, tx, ty, diagonal, hmul)
            fu = ng + hu
            seq -= 1
            size = _heap_push(hf, hh, hv, size, fu, hu, (seq << 32) | u)
    return 0, np.inf, size, seq, expanded


@njit(cache=True, nogil=True)
def trace(s, t, w, pdir):
    """Flat cells of the path from ``s`` to ``t`` by following ``pdir`` backwards."""
    n = 1
    v = t
    while v != s:
        d = pdir[v]
        v = v - DY[d] * w - DX[d]
        n += 1
    out = np.empty(n, dtype=np.int64)
    v = t
    i = n - 1
    out[i] = v
    while v != s:
        d = pdir[v]
        v = v - DY[d] * w - DX[d]
        i -= 1
        out[i] = v
    return out


@njit(cache=True, nogil=True)
def label(free, w, h, bsize):
    """Label 4-connected free regions, never crossing ``bsize`` block borders.

    With ``bsize >= max(w, h)`` these are the map's connected components (also those of
    8-connectivity without corner cutting, since every allowed diagonal step has a free
    orthogonal detour). Returns (labels int32, -1 on walls; number of labels).
    """
    n = w * h
    labels = np.full(n, -1, dtype=np.int32)
    stack = np.empty(n, dtype=np.int32)
    nlab = 0
    for v0 in range(n):
        if free[v0] == 0 or labels[v0] >= 0:
            continue
        labels[v0] = nlab
        top = 0
        stack[0] = v0
        top = 1
        while top > 0:
            top -= 1
            v = stack[top]
            x = v % w
            y = v // w
            bx = x // bsize
            by = y // bsize
            for d in range(4):
                nx = x + DX[d]
                ny = y + DY[d]
                if nx < 0 or ny < 0 or nx >= w or ny >= h:
                    continue
                if nx // bsize != bx or ny // bsize != by:
                    continue
                u = ny * w + nx
                if free[u] != 0 and labels[u] < 0:
                    labels[u] = nlab
                    stack[top] = u
                    top += 1
        nlab += 1
    return labels, nlab


@njit(cache=True, nogil=True)
def portal_search(indptr, indices, weights, px, py, src_d, tgt_d, direct, diagonal, hmul, tx, ty):
    """Abstract search over portals (points on block borders) for the hierarchical mode.

    Every portal p starts with g = ``src_d[p]`` (inf unless p borders the start's region)
    and may finish at the goal at extra cost ``tgt_d[p]`` (inf unless it borders the
    goal's region); ``direct`` is the start→goal cost when they share a region. Returns
    the portal sequence of the cheapest route (empty for the direct route) and its cost
    (inf when the goal is unreachable).
    """
    n = indptr.shape[0] - 1
    g = src_d.copy()
    parent = np.full(n, -1, dtype=np.int64)
    closed = np.zeros(n, dtype=np.uint8)
    # every push is a start portal or an edge relaxation: this never overflows, so the
    # loop never rebinds its arrays (slow in numba)
    cap = n + indices.shape[0] + 1
    hk = np.empty(cap, dtype=np.float64)
    hv = np.empty(cap, dtype=np.int64)
    size = 0
    best = direct
    best_end = -1
    for p in range(n):
        if g[p] < np.inf:
            f = g[p] + _heuristic(px[p], py[p], tx, ty, diagonal, hmul)
            i = size
            size += 1
            while i > 0:
                q = (i - 1) >> 1
                if f < hk[q]:
                    hk[i] = hk[q]
                    hv[i] = hv[q]
                    i = q
                else:
                    break
            hk[i] = f
            hv[i] = p
    while size > 0:
        v = hv[0]
        vf = hk[0]
        if vf >= best:
            break
        size -= 1
        if size > 0:
            lk = hk[size]
            lv = hv[size]
            i = 0
            while True:
                c = 2 * i + 1
                if c >= size:
                    break
                if c + 1 < size and hk[c + 1] < hk[c]:
                    c += 1
                if hk[c] < lk:
                    hk[i] = hk[c]
                    hv[i] = hv[c]
                    i = c
                else:
                    break
            hk[i] = lk
            hv[i] = lv
        if closed[v]:
            continue
        closed[v] = 1
        if g[v] + tgt_d[v] < best:
            best = g[v] + tgt_d[v]
            best_end = v
        for j in range(indptr[v], indptr[v + 1]):
            u = indices[j]
            if closed[u]:
                continue
            ng = g[v] + weights[j]
            if ng < g[u]:
                g[u] = ng
                parent[u] = v
                f = ng + _heuristic(px[u], py[u], tx, ty, diagonal, hmul)
                i = size
                size += 1
                while i > 0:
                    q = (i - 1) >> 1
                    if f < hk[q]:
                        hk[i] = hk[q]
                        hv[i] = hv[q]
                        i = q
                    else:
                        break
                hk[i] = f
                hv[i] = u
    if best_end < 0:
        return np.empty(0, dtype=np.int64), best
    m = 1
    v = best_end
    while parent[v] >= 0:
        v = parent[v]
        m += 1
    out = np.empty(m, dtype=np.int64)
    v = best_end
    for i in range(m - 1, -1, -1):
        out[i] = v
        v = parent[v]
    return out, best


@njit(cache=True, nogil=True)
def region_pair_edges(starts, members, px, py, diagonal, hmul):
    """All ordered pairs of portals bordering the same region, with their distance.

    ``members[starts[r]:starts[r+1]]`` are the portals of region r.
    """
    m = 0
    for r in range(starts.shape[0] - 1):
        k = starts[r + 1] - starts[r]
        m += k * (k - 1)
    src = np.empty(m, dtype=np.int64)
    dst = np.empty(m, dtype=np.int64)
    wt = np.empty(m, dtype=np.float64)
    j = 0
    for r in range(starts.shape[0] - 1):
        for a in range(starts[r], starts[r + 1]):
            pa = members[a]
            for b in range(starts[r], starts[r + 1]):
                if a == b:
                    continue
                pb = members[b]
                src[j] = pa
                dst[j] = pb
                dx = abs(px[pa] - px[pb])
                dy = abs(py[pa] - py[pb])
                if diagonal:
                    wt[j] = hmul * (max(dx, dy) + (SQRT2 - 1.0) * min(dx, dy))
                else:
                    wt[j] = hmul * (dx + dy)
                j += 1
    return src, dst, wt


@njit(cache=True, nogil=True)
def _heap_init(s, t, w, diagonal, hmul, g, stamp, epoch):
    cap = 4096
    hf = np.empty(cap, dtype=np.float64)
    hh = np.empty(cap, dtype=np.float64)
    hv = np.empty(cap, dtype=np.int64)
    seq = np.int64(1) << 30
    g[s] = 0.0
    stamp[s] = 2 * epoch
    hf[0] = _heuristic(s % w, s // w, t % w, t // w, diagonal, hmul)
    hh[0] = hf[0]
    hv[0] = (seq << 32) | s
    return hf, hh, hv, seq


@njit(cache=True, nogil=True)
def astar_both(free, cost, w, h, s, t, diagonal, hmul, allow, bsize, bw,
               g, stamp, pdir, g2, stamp2, pdir2, epoch, first_budget, probe=False):
    """Exact A* s→t that hedges against a bad search direction.

    The forward search runs alone for ``first_budget`` expansions (enough for most
    queries); if it has not finished, a reverse search (t→s, in ``g2``/``stamp2``/``pdir2``)
    starts and both advance in turns, each resuming where it stopped, with a doubling
    budget, until one finishes. Each search is exact, so either answer is optimal, and the
    work is at most about twice that of the better direction (plus ``first_budget``).
    Returns (cost or inf, total expanded, 1 if the reverse search answered else 0); with
    ``probe``, a forward search that has not finished within ``first_budget`` stops there
    and returns (-1, expanded, 2).
    """
    fhf, fhh, fhv, fseq = _heap_init(s, t, w, diagonal, hmul, g, stamp, epoch)
    fsize = 1
    fexp = 0
    budget = first_budget
    while True:
        st, res, fsize, fseq, fexp = _astar_core(
            free, cost, w, h, t, diagonal, hmul, allow, bsize, bw, g, stamp, epoch, pdir,
            False, budget, fhf, fhh, fhv, fsize, fseq, fexp)
        if st == 1:
            fhf = _grow(fhf, fsize)
            fhh = _grow(fhh, fsize)
            fhv = _grow(fhv, fsize)
            continue
        if st == 0:
            return res, fexp, 0
        if probe:
            return -1.0, fexp, 2
        break
    rhf, rhh, rhv, rseq = _heap_init(t, s, w, diagonal, hmul, g2, stamp2, epoch)
    rsize = 1
    rexp = 0
    rbudget = 0
    while True:
        rbudget = max(rbudget * 2, fexp)
        while True:
            st, res, rsize, rseq, rexp = _astar_core(
                free, cost, w, h, s, diagonal, hmul, allow, bsize, bw, g2, stamp2, epoch,
                pdir2, True, rbudget, rhf, rhh, rhv, rsize, rseq, rexp)
            if st == 1:
                rhf = _grow(rhf, rsize)
                rhh = _grow(rhh, rsize)
                rhv = _grow(rhv, rsize)
                continue
            break
        if st == 0:
            return res, fexp + rexp, 1
        budget = 2 * budget if budget >= rexp else rexp
        while True:
            st, res, fsize, fseq, fexp = _astar_core(
                free, cost, w, h, t, diagonal, hmul, allow, bsize, bw, g, stamp, epoch, pdir,
                False, budget, fhf, fhh, fhv, fsize, fseq, fexp)
            if st == 1:
                fhf = _grow(fhf, fsize)
                fhh = _grow(fhh, fsize)
                fhv = _grow(fhv, fsize)
                continue
            break
        if st == 0:
            return res, fexp + rexp, 0


@njit(cache=True, nogil=True)
def _fill_spans(free, w, h, t, sx, sy, top):
    """Scanline flood fill over 4-connected free cells, resumable: pops seeds from the
    stack ``sx``/``sy`` (``top`` entries) and marks whole runs of a row at once, in ``free``
    itself (1 = free, 2 = free and reached). Returns (status, top): 1 when ``t`` was reached,
    0 when the fill ran out (``t`` not reachable), 2 when the stack is full (grow it and call
    again)."""
    cap = sx.shape[0]
    while top > 0:
        if top + w + 2 > cap:  # one run pushes at most w + 2 seeds (both rows)
            return 2, top
        top -= 1
        x = sx[top]
        y = sy[top]
        row = y * w
        if free[row + x] != 1:
            continue
        lo = x
        while lo > 0 and free[row + lo - 1] == 1:
            lo -= 1
        hi = x
        while hi + 1 < w and free[row + hi + 1] == 1:
            hi += 1
        for i in range(row + lo, row + hi + 1):
            free[i] = 2
        if row + lo <= t <= row + hi:
            return 1, top
        for ny in (y - 1, y + 1):
            if ny < 0 or ny >= h:
                continue
            nrow = ny * w
            inrun = False
            for nx in range(lo, hi + 1):
                ok = free[nrow + nx] == 1
                if ok and not inrun:
                    sx[top] = nx
                    sy[top] = ny
                    top += 1
                inrun = ok
    return 0, top


@njit(cache=True, nogil=True)
def connected(free, w, h, s, t):
    """Whether free cell ``t`` is reachable from free cell ``s`` over 4-connected free cells
    (the same components as 8-connectivity without corner cutting; see :func:`label`).

    A scanline flood fill from ``s`` that stops as soon as it reaches ``t``: the "no path"
    answer of a one-off query without labelling the whole map. ``free`` holds 0 (wall) or 1
    (free); the fill marks every cell it reaches with 2 in place (still nonzero, so still
    free to every kernel, but no longer a 0/1 mask: pass a copy to keep one).
    """
    sx = np.empty(4 * w + 64, dtype=np.int32)
    sy = np.empty(4 * w + 64, dtype=np.int32)
    sx[0] = s % w
    sy[0] = s // w
    top = 1
    while True:
        st, top = _fill_spans(free, w, h, t, sx, sy, top)
        if st != 2:
            return st == 1
        sx = _grow(sx, top)
        sy = _grow(sy, top)


# -- uniform cost, 4-connected: a bucket queue over a tiled layout ---------------------
# With unit steps and the Manhattan heuristic every f is the current f or the current f + 2,
# so the open list is two buckets: ``cur`` (f = fcur) and ``nxt`` (f = fcur + 2). Inside a
# bucket the order is that of the heap kernel (smaller h, then most recently pushed): a node
# popped from ``cur`` has the smallest h there, and its successors in ``cur`` have h one
# less, so ``cur`` is a plain stack; ``nxt`` is sorted once when it becomes ``cur``.
# The work array ``state`` holds (mark << 32) | (g << 1) | closed per cell in one int64,
# indexed by 32×32 tiles so that a search that runs down a column touches one page per 32
# cells instead of one per cell.
TILE_SHIFT = 5
TILE = 1 << TILE_SHIFT


@njit(cache=True, inline="always", nogil=True)
def _tix(x, y, tw):
    return ((((y >> TILE_SHIFT) * tw + (x >> TILE_SHIFT)) << (2 * TILE_SHIFT))
            | ((y & (TILE - 1)) << TILE_SHIFT) | (x & (TILE - 1)))


def tiled_size(w: int, h: int) -> tuple[int, int]:
    """(tiles per row, entries) of a work array in the tiled layout of a w×h map."""
    tw = (w + TILE - 1) >> TILE_SHIFT
    th = (h + TILE - 1) >> TILE_SHIFT
    return tw, tw * th * TILE * TILE


@njit(cache=True, nogil=True)
def _uni_core(free, w, h, tw, t, allow, bsize, bw, state, pdir, mark, budget,
              cur, ncur, nxt, nnext, fcur, expanded):
    """The uniform-cost A* loop, resumable like :func:`_astar_core`: returns (status, cost,
    ncur, nnext, fcur, expanded), status 0 done (cost, or -1 when there is no path), 1 a
    bucket is full (grow both and call again), 2 ``budget`` expansions reached."""
    restrict = allow.shape[0] > 0
    tx = t % w
    ty = t // w
    hi = np.int64(mark) << 32
    ccap = cur.shape[0]
    ncap = nxt.shape[0]
    while True:
        if ncur == 0:
            if nnext == 0:
                return 0, -1, ncur, nnext, fcur, expanded
            if nnext > ccap:
                return 1, 0, ncur, nnext, fcur, expanded
            # nxt becomes cur: smaller h on top, and the later pushed first among equal h
            key = np.empty(nnext, dtype=np.int64)
            for i in range(nnext):
                u = nxt[i]
                key[i] = -(abs(u % w - tx) + abs(u // w - ty))
            order = np.argsort(key, kind="mergesort")
            for i in range(nnext):
                cur[i] = nxt[order[i]]
            ncur = nnext
            nnext = 0
            fcur += 2
            continue
        if ncur + 4 > ccap or nnext + 4 > ncap:
            return 1, 0, ncur, nnext, fcur, expanded
        if budget > 0 and expanded >= budget:
            return 2, 0, ncur, nnext, fcur, expanded
        ncur -= 1
        v = cur[ncur]
        y = v // w
        x = v - y * w
        iv = _tix(x, y, tw)
        sv = state[iv]
        if sv & 1:
            continue  # closed (a stale entry): only this search's marks are ever read here
        gv = (sv & 0xFFFFFFFF) >> 1
        state[iv] = sv | 1
        expanded += 1
        if v == t:
            return 0, gv, ncur, nnext, fcur, expanded
        ng = gv + 1
        for d in range(4):
            nx = x + DX[d]
            ny = y + DY[d]
            if nx < 0 or ny < 0 or nx >= w or ny >= h:
                continue
            u = ny * w + nx
            if free[u] == 0:
                continue
            if restrict and allow[(ny // bsize) * bw + nx // bsize] == 0:
                continue
            iu = _tix(nx, ny, tw)
            su = state[iu]
            if (su >> 32) == mark and (su & 1 or ((su & 0xFFFFFFFF) >> 1) <= ng):
                continue
            state[iu] = hi | (ng << 1)
            pdir[iu] = d
            if ng + abs(nx - tx) + abs(ny - ty) == fcur:
                cur[ncur] = u
                ncur += 1
            else:
                nxt[nnext] = u
                nnext += 1


@njit(cache=True, nogil=True)
def _uni_init(s, t, w, tw, state, mark):
    cur = np.empty(4096, dtype=np.int32)
    nxt = np.empty(4096, dtype=np.int32)
    state[_tix(s % w, s // w, tw)] = np.int64(mark) << 32
    cur[0] = s
    return cur, nxt, abs(s % w - t % w) + abs(s // w - t // w)


@njit(cache=True, nogil=True)
def _uni_run(free, w, h, tw, t, allow, bsize, bw, state, pdir, mark, budget,
             cur, ncur, nxt, nnext, fcur, expanded):
    """Run :func:`_uni_core` until done or out of budget, growing the buckets as needed;
    returns (status, cost, cur, ncur, nxt, nnext, fcur, expanded)."""
    while True:
        st, res, ncur, nnext, fcur, expanded = _uni_core(
            free, w, h, tw, t, allow, bsize, bw, state, pdir, mark, budget,
            cur, ncur, nxt, nnext, fcur, expanded)
        if st != 1:
            return st, res, cur, ncur, nxt, nnext, fcur, expanded
        cap = max(cur.shape[0], nxt.shape[0], ncur + 8, nnext + 8)
        if cur.shape[0] < 2 * cap:
            c2 = np.empty(2 * cap, dtype=np.int32)
            c2[:ncur] = cur[:ncur]
            cur = c2
        if nxt.shape[0] < 2 * cap:
            n2 = np.empty(2 * cap, dtype=np.int32)
            n2[:nnext] = nxt[:nnext]
            nxt = n2


@njit(cache=True, nogil=True)
def astar_uniform_both(free, w, h, s, t, allow, bsize, bw, state, pdir, state2, pdir2,
                       mark, first_budget, probe=False):
    """:func:`astar_both` for uniform cost 1 and 4 directions, on the bucket queue and the
    tiled work arrays (``state``/``pdir`` forward, ``state2``/``pdir2`` reverse, each
    :func:`tiled_size` entries; ``mark`` > every mark already in them). Same turns, same
    answers: returns (cost or -1, total expanded, 0 forward / 1 reverse / 2 probe stopped)."""
    tw = (w + TILE - 1) >> TILE_SHIFT
    cur, nxt, fcur = _uni_init(s, t, w, tw, state, mark)
    ncur = 1
    nnext = 0
    fexp = 0
    budget = first_budget
    st, res, cur, ncur, nxt, nnext, fcur, fexp = _uni_run(
        free, w, h, tw, t, allow, bsize, bw, state, pdir, mark, budget,
        cur, ncur, nxt, nnext, fcur, fexp)
    if st == 0:
        return res, fexp, 0
    if probe:
        return -1, fexp, 2
    rcur, rnxt, rfcur = _uni_init(t, s, w, tw, state2, mark)
    rncur = 1
    rnnext = 0
    rexp = 0
    rbudget = 0
    while True:
        rbudget = max(rbudget * 2, fexp)
        st, res, rcur, rncur, rnxt, rnnext, rfcur, rexp = _uni_run(
            free, w, h, tw, s, allow, bsize, bw, state2, pdir2, mark, rbudget,
            rcur, rncur, rnxt, rnnext, rfcur, rexp)
        if st == 0:
            return res, fexp + rexp, 1
        budget = 2 * budget if budget >= rexp else rexp
        st, res, cur, ncur, nxt, nnext, fcur, fexp = _uni_run(
            free, w, h, tw, t, allow, bsize, bw, state, pdir, mark, budget,
            cur, ncur, nxt, nnext, fcur, fexp)
        if st == 0:
            return res, fexp + rexp, 0


@njit(cache=True, nogil=True)
def trace_tiled(s, t, w, pdir):
    """:func:`trace` for a ``pdir`` in the tiled layout."""
    tw = (w + TILE - 1) >> TILE_SHIFT
    n = 1
    v = t
    while v != s:
        d = pdir[_tix(v % w, v // w, tw)]
        v = v - DY[d] * w - DX[d]
        n += 1
    out = np.empty(n, dtype=np.int64)
    v = t
    i = n - 1
    out[i] = v
    while v != s:
        d = pdir[_tix(v % w, v // w, tw)]
        v = v - DY[d] * w - DX[d]
        i -= 1
        out[i] = v
    return out


# 8-connected queries on uniform-cost maps run on jump point search (its own module).
from robo_comp.world._jps import jps, trace as trace_jumps  # noqa: E402

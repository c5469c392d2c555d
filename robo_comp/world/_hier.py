"""Hierarchical search for :class:`robo_comp.world.planner.Planner` (private).

The thesis's "high-level map" done right. The map is cut into ``block``×``block`` blocks
(any map size: edge blocks may be smaller); each block's free cells split into regions
(4-connected inside the block), so a block a wall crosses is not simply "blocked" as in
the thesis but holds one region per side. Where two regions touch across a block border,
each contiguous stretch of shared border is a *portal*; portals bordering the same region
are linked by their straight-line (octile or Manhattan) distance. A query searches this
portal graph from the start to the goal, then runs exact A* on the real grid restricted to
the blocks of the regions on that route plus a one-block margin. That corridor always
connects start and goal (each region is connected and consecutive regions touch), and if
anything still fails the planner falls back to a full optimal search.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from robo_comp.world.paths import PathResult
from robo_comp.world.paths import kernels as _k


def default_block(width: int, height: int) -> int:
    """Block edge: about 64 blocks across the longer side, at least 16 cells."""
    return max(16, math.ceil(max(width, height) / 64))


def _runs(lines: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Contiguous runs of equal non-negative keys in each line: (line, start, end, key)."""
    lid, st, en, ky = [], [], [], []
    for i, key in enumerate(lines):
        if key.size == 0:
            continue
        change = np.flatnonzero(np.diff(key) != 0) + 1
        starts = np.concatenate(([0], change))
        ends = np.concatenate((change, [key.size])) - 1
        keep = key[starts] >= 0
        starts, ends = starts[keep], ends[keep]
        lid.append(np.full(starts.size, i, dtype=np.int64))
        st.append(starts)
        en.append(ends)
        ky.append(key[starts])
    if not lid:
        e = np.empty(0, dtype=np.int64)
        return e, e, e, e
    return (np.concatenate(lid), np.concatenate(st), np.concatenate(en), np.concatenate(ky))


class Hierarchy:
    """The portal graph of one planner's map."""

    def __init__(self, planner: Any, block: int | None = None) -> None:
        """``planner``: the :class:`~robo_comp.world.planner.Planner` whose map this graph covers."""
        k = _k()
        self.p = planner
        w, h = planner.width, planner.height
        self.block = b = int(block) if block else default_block(w, h)
        self.bw = -(-w // b)
        self.bh = -(-h // b)
        labels, nreg = k.label(planner._free, w, h, b)
        self.labels = labels
        lab2 = labels.reshape(h, w).astype(np.int64)
        vx = list(range(b, w, b))
        hy = list(range(b, h, b))
        lines_a = [lab2[:, x - 1] for x in vx] + [lab2[y - 1, :] for y in hy]
        lines_b = [lab2[:, x] for x in vx] + [lab2[y, :] for y in hy]
        keys = [np.where((a >= 0) & (c >= 0), a * nreg + c, -1)
                for a, c in zip(lines_a, lines_b)]
        lid, st, en, key = _runs(keys)
        mid = (st + en) // 2
        nv = len(vx)
        vertical = lid < nv
        border = np.array(vx + hy, dtype=np.int64)[lid] if lid.size else lid
        self.px = np.where(vertical, border - 0.5, mid).astype(np.float64)
        self.py = np.where(vertical, mid, border - 0.5).astype(np.float64)
        ra, rb = key // max(nreg, 1), key % max(nreg, 1)
        npt = key.size
        # cells on either side of each portal: their blocks form the corridor
        ax = np.where(vertical, border - 1, mid)
        ay = np.where(vertical, mid, border - 1)
        bx = np.where(vertical, border, mid)
        by = np.where(vertical, mid, border)
        self.block_a = (ay // b) * self.bw + ax // b
        self.block_b = (by // b) * self.bw + bx // b
        region = np.concatenate([ra, rb])
        portal = np.concatenate([np.arange(npt), np.arange(npt)])
        order = np.argsort(region, kind="stable")
        self.members = portal[order]
        self.starts = np.zeros(nreg + 1, dtype=np.int64)
        np.cumsum(np.bincount(region, minlength=nreg), out=self.starts[1:])
        src, dst, wt = k.region_pair_edges(self.starts, self.members, self.px, self.py,
                                           planner.diagonal, planner._hmul)
        order = np.argsort(src, kind="stable")
        self.indices = dst[order]
        self.weights = wt[order]
        self.indptr = np.zeros(npt + 1, dtype=np.int64)
        np.cumsum(np.bincount(src, minlength=npt), out=self.indptr[1:])
        self.nportals = npt
        self.nregions = nreg

    def _dist(self, x: float | np.ndarray, y: float | np.ndarray, x2: float, y2: float
              ) -> np.ndarray:
        dx = np.abs(np.asarray(x) - x2)
        dy = np.abs(np.asarray(y) - y2)
        if self.p.diagonal:
            d = np.maximum(dx, dy) + (math.sqrt(2) - 1) * np.minimum(dx, dy)
        else:
            d = dx + dy
        return d * self.p._hmul

    def corridor(self, s: int, t: int, margin: int = 1) -> np.ndarray | None:
        """Block mask (uint8, bh*bw) around the abstract route s→t, or None if none."""
        w, b = self.p.width, self.block
        sx, sy, tx, ty = s % w, s // w, t % w, t // w
        rs, rt = int(self.labels[s]), int(self.labels[t])
        src_d = np.full(self.nportals, np.inf)
        tgt_d = np.full(self.nportals, np.inf)
        ps = self.members[self.starts[rs]:self.starts[rs + 1]]
        pt = self.members[self.starts[rt]:self.starts[rt + 1]]
        src_d[ps] = self._dist(self.px[ps], self.py[ps], sx, sy)
        tgt_d[pt] = self._dist(self.px[pt], self.py[pt], tx, ty)
        direct = float(self._dist(sx, sy, tx, ty)) if rs == rt else math.inf
        route, cost = _k().portal_search(self.indptr, self.indices, self.weights, self.px,
                                         self.py, src_d, tgt_d, direct, self.p.diagonal,
                                         self.p._hmul, float(tx), float(ty))
        if math.isinf(cost):
            return None
        blocks = np.concatenate([self.block_a[route], self.block_b[route],
                                 [(sy // b) * self.bw + sx // b, (ty // b) * self.bw + tx // b]])
        mask = np.zeros((self.bh, self.bw), dtype=np.uint8)
        byy, bxx = np.divmod(blocks.astype(np.int64), self.bw)
        for dy in range(-margin, margin + 1):
            for dx in range(-margin, margin + 1):
                mask[np.clip(byy + dy, 0, self.bh - 1), np.clip(bxx + dx, 0, self.bw - 1)] = 1
        return mask.reshape(-1)

    def find(self, s: int, t: int) -> PathResult:
        """Near-optimal path s→t: portal search, then exact A* inside the corridor."""
        w = self.p.width
        if abs(s % w - t % w) + abs(s // w - t // w) <= 4 * self.block:
            # Short hop: a plain exact search is as cheap as the abstraction.
            return self.p.find_optimal((s % w, s // w), (t % w, t // w))
        mask = self.corridor(s, t)
        if mask is not None:
            cost, expanded, path = self.p._search(s, t, mask, self.block, self.bw)
            if path is not None:
                return PathResult(path, cost, expanded)
        # Fallback: the abstract search or the corridor failed; the full search decides.
        return self.p.find_optimal((s % w, s // w), (t % w, t // w))

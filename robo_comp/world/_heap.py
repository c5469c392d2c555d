"""The compiled searches' open list: a binary heap in three parallel arrays (f, h, key).

Private module of the planner's kernels (``_kernels``, ``_jps``). An entry is ``f`` (cost so far
plus heuristic), ``h`` (the heuristic) and ``k``, a decreasing push counter shifted above the
cell index (``(seq << 32) | cell``). The order is by f; ties go to smaller h (deeper nodes),
then to the most recently pushed entry: on plateaus of equal f this follows one branch to its
end instead of widening the whole front. The arrays are the caller's: a search never rebinds
them inside its loop (in numba that costs several times the search), it returns to a caller
that grows them (:func:`grow`) and resumes.
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, inline="always", nogil=True)
def less(f1, h1, k1, f2, h2, k2):
    """Whether entry (f1, h1, k1) comes before (f2, h2, k2)."""
    return f1 < f2 or (f1 == f2 and (h1 < h2 or (h1 == h2 and k1 < k2)))


@njit(cache=True, inline="always", nogil=True)
def push(hf, hh, hv, size, f, h, k):
    """Add an entry to the heap of ``size`` entries (the arrays must have room); the new size."""
    i = size
    while i > 0:
        p = (i - 1) >> 1
        if less(f, h, k, hf[p], hh[p], hv[p]):
            hf[i] = hf[p]
            hh[i] = hh[p]
            hv[i] = hv[p]
            i = p
        else:
            break
    hf[i] = f
    hh[i] = h
    hv[i] = k
    return size + 1


@njit(cache=True, inline="always", nogil=True)
def pop(hf, hh, hv, size):
    """Remove the least entry (the caller reads it at index 0 first); the new size."""
    size -= 1
    if size > 0:
        lf = hf[size]
        lh = hh[size]
        lv = hv[size]
        i = 0
        while True:
            c = 2 * i + 1
            if c >= size:
                break
            if c + 1 < size and less(hf[c + 1], hh[c + 1], hv[c + 1], hf[c], hh[c], hv[c]):
                c += 1
            if less(hf[c], hh[c], hv[c], lf, lh, lv):
                hf[i] = hf[c]
                hh[i] = hh[c]
                hv[i] = hv[c]
                i = c
            else:
                break
        hf[i] = lf
        hh[i] = lh
        hv[i] = lv
    return size


@njit(cache=True, nogil=True)
def grow(a, size):
    """A copy of ``a`` twice as long, its first ``size`` entries kept."""
    out = np.empty(a.shape[0] * 2, dtype=a.dtype)
    out[:size] = a[:size]
    return out

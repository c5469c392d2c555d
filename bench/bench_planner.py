"""Benchmark the planner on the thesis's figure 5.1 maps (start top-left, goal bottom-right).

Compares, per map kind 1..5 and size: the thesis-style baseline (bench/thesis_astar.py),
python-tcod's C A* (tcod.path.AStar, 4-connected), our optimal A* and our hierarchical
mode, and pyastar2d's C++ A* (4-connected, nothing to prepare). "ours" is a query on a prepared
planner; "one-shot" is ``find_path`` (a planner built for one query, no preparation kept);
"prep+query" is preparation plus one query; "vs pyastar2d" compares pyastar2d with the better
of our one-shot and prep+query (above 1: we are faster with preparation counted).

    .venv/bin/python bench/bench_planner.py [--sizes 100,300,1000,2000,5000]
        [--baseline-cap 30] [--baseline-max 2000] [--markdown]

Times are the best of 3 runs (2 from size 2000; tcod 1 at 5000).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402

from robo_comp.world.maps import thesis_map  # noqa: E402


def _timed(fn, repeat: int = 1):
    best = float("inf")
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def _fmt(t: float | None) -> str:
    if t is None:
        return "-"
    return f"{t * 1e3:.2f}ms" if t < 1 else f"{t:.2f}s"


def _ratio(a: float | None, b: float | None) -> str:
    if a is None or b is None or b <= 0:
        return "-"
    return f"{a / b:.0f}x" if a / b >= 10 else f"{a / b:.2f}x"


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print a table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="100,300,1000,2000,5000")
    ap.add_argument("--baseline-cap", type=float, default=30.0,
                    help="seconds before a baseline run is abandoned (shown as >cap)")
    ap.add_argument("--baseline-max", type=int, default=2000,
                    help="largest size the baseline runs at (its list-of-lists map alone "
                         "takes seconds to build at 5000)")
    ap.add_argument("--no-tcod", action="store_true")
    ap.add_argument("--markdown", action="store_true", help="print a markdown table")
    args = ap.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",") if s]

    t0 = time.perf_counter()
    from robo_comp.world import planner as pl
    t_import = time.perf_counter() - t0
    t_jit = pl.warm_up()
    print(f"import robo_comp.world.planner: {t_import * 1e3:.1f} ms; first-call JIT "
          f"(compile, or load from numba's on-disk cache): {t_jit:.2f} s", flush=True)
    from thesis_astar import thesis_astar

    tcod_path = None
    if not args.no_tcod:
        try:
            import tcod.path as tcod_path
        except ImportError:
            print("tcod not installed (pip install -e '.[bench]'): skipping it")

    try:
        import pyastar2d
    except ImportError:
        pyastar2d = None
        print("pyastar2d not installed (pip install -e '.[bench]'): skipping it")
    head = ["size", "map", "baseline", "tcod A*", "pyastar2d", "ours", "vs tcod", "vs base",
            "one-shot", "prep+query", "vs pyastar2d", "hier", "hier/opt", "prep opt", "prep hier", "expanded"]
    rows = []
    for n in sizes:
        for kind in range(1, 6):
            m = thesis_map(kind, n)
            s, g = (0, 0), (n - 1, n - 1)
            base = None
            if n <= args.baseline_max:
                grid = m.walls.astype(np.int8).tolist()
                try:
                    base, _ = _timed(lambda: thesis_astar(
                        grid, s, g, deadline=time.perf_counter() + args.baseline_cap))
                    base_s = _fmt(base)
                except TimeoutError:
                    base, base_s = None, f">{args.baseline_cap:.0f}s"
                del grid
            else:
                base_s = "skipped"
            rep = 3 if n <= 1000 else 2
            tc = None
            if tcod_path is not None:
                astar = tcod_path.AStar((~m.walls).astype(np.int8), diagonal=0)
                tc, tpath = _timed(lambda: astar.get_path(s[0], s[1], g[0], g[1]),
                                   rep if n < 5000 else 1)
                del astar
            pa = None
            if pyastar2d is not None:  # C++ A*, 4-connected, weights 1 and inf for walls: nothing to prepare
                weights = np.where(m.walls, np.inf, 1.0).astype(np.float32)
                pa, _ = _timed(lambda: pyastar2d.astar_path(weights, (s[1], s[0]), (g[1], g[0])), rep)
                del weights
            one, _ = _timed(lambda: pl.find_path(m.walls, s, g), rep)  # a one-off query: no preparation kept
            prep_o, p = _timed(lambda: pl.Planner(m.walls).prepare())
            t_opt, r = _timed(lambda: p.find(s, g), rep)
            del p
            prep_h, ph = _timed(lambda: pl.Planner(m.walls, hierarchical=True).prepare())
            t_h, rh = _timed(lambda: ph.find(s, g), rep)
            del ph
            if r.cost is not None:
                quality = f"{rh.cost / r.cost:.4f}"
            else:
                quality = "no path" if rh.cost is None else "WRONG"
            best_ours = min(one, prep_o + t_opt)  # what a single query costs us, preparation counted
            rows.append([str(n), str(kind), base_s, _fmt(tc), _fmt(pa), _fmt(t_opt), _ratio(tc, t_opt),
                         _ratio(base, t_opt), _fmt(one), _fmt(prep_o + t_opt), _ratio(pa, best_ours),
                         _fmt(t_h), quality, _fmt(prep_o), _fmt(prep_h), str(r.expanded)])
            print("  ".join(rows[-1]), flush=True)
    print()
    if args.markdown:
        print("| " + " | ".join(head) + " |")
        print("|" + "---|" * len(head))
        for row in rows:
            print("| " + " | ".join(row) + " |")
    else:
        widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
        print("  ".join(h.rjust(wd) for h, wd in zip(head, widths)))
        for row in rows:
            print("  ".join(c.rjust(wd) for c, wd in zip(row, widths)))
    return 0


if __name__ == "__main__":
    sys.exit(main())

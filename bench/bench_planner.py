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

One-shot mode (issue 31): one query (0,0)→(n−1,n−1) with nothing prepared, each contender in
a fresh child process, min / median / max of ``--reps`` queries and the child's peak memory:

    .venv/bin/python bench/bench_planner.py --oneshot [--cases 2:5000,5:1000,5:2000,5:5000]
        [--reps 3] [--before REV]

Contenders: ``find_path`` of this tree; ``find_path`` of git revision ``--before`` (default
``4cf6a9a``, the planner before issue 31; ``--before ''`` skips it); python-tcod
(``tcod.path.AStar(cost, diagonal=0)`` built and asked inside the timing); pyastar2d
(``astar_path`` on float32 weights, 1 and inf for walls, made outside the timing). Memory is
the child's peak RSS (``ru_maxrss``) after the queries, and how much the queries added to it
(the map and each peer's input array are made before the "before" reading).
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any

# --oneshot runs each contender in a child; BENCH_PLANNER_TREE names the robo_comp tree it imports
sys.path.insert(0, os.environ.get("BENCH_PLANNER_TREE", str(Path(__file__).resolve().parent.parent)))
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


BEFORE_REV = "4cf6a9a"  # main before issue 31's planner work


def _child(who: str, kind: int, n: int, reps: int) -> dict[str, object]:
    """One contender's one-shot queries in this (fresh) process: times and memory."""
    import resource

    def rss_mib() -> float:
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024

    walls = thesis_map(kind, n).walls
    s, g = (0, 0), (n - 1, n - 1)
    if who in ("ours", "before"):
        from robo_comp.world import planner as pl

        assert Path(pl.__file__).resolve().is_relative_to(Path(os.environ.get(
            "BENCH_PLANNER_TREE", Path(__file__).resolve().parent.parent)).resolve())
        pl.warm_up()
        run = lambda: pl.find_path(walls, s, g)  # noqa: E731
        found = lambda out: out is not None  # noqa: E731
    elif who == "tcod":
        import tcod.path

        cost = (~walls).astype(np.int8)
        run = lambda: tcod.path.AStar(cost, diagonal=0).get_path(s[0], s[1], g[0], g[1])  # noqa: E731
        found = lambda out: len(out) > 0  # noqa: E731
    else:
        import pyastar2d

        weights = np.where(walls, np.inf, 1.0).astype(np.float32)
        run = lambda: pyastar2d.astar_path(weights, (s[1], s[0]), (g[1], g[0]))  # noqa: E731
        found = lambda out: out is not None  # noqa: E731
    before = rss_mib()
    times = []
    out = None
    for _ in range(reps):
        t0 = time.perf_counter()
        out = run()
        times.append(time.perf_counter() - t0)
        del out
        out = None
    out = run()
    return {"times": times, "rss_before": before, "rss_peak": rss_mib(), "found": bool(found(out))}


def oneshot(args: argparse.Namespace) -> int:
    """One-shot queries, each contender in a fresh child process, beside the peers."""
    import json
    import statistics
    import subprocess
    import tempfile

    cases = [tuple(int(v) for v in c.split(":")) for c in args.cases.split(",") if c]
    here = Path(__file__).resolve()
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"ours": str(here.parent.parent)}
        if args.before:
            old = Path(tmp) / "before"
            old.mkdir()
            archive = subprocess.run(["git", "-C", trees["ours"], "archive", args.before, "robo_comp"],
                                     capture_output=True, check=True).stdout
            subprocess.run(["tar", "-x", "-C", str(old)], input=archive, check=True)
            trees["before"] = str(old)
        who_all = [w for w in ("ours", "before", "tcod", "pyastar2d") if w in trees or w in args.peers]
        print(f"one-shot find_path, (0,0)->(n-1,n-1), {args.reps} queries per contender, each "
              f"contender in a fresh process; before = {args.before or '-'}; load: "
              f"{os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}", flush=True)
        head = ["map", "size", "contender", "min", "median", "max", "path", "peak MiB", "+MiB",
                "ours vs it (median)", "load"]
        rows = []
        for kind, n in cases:
            res = {}
            for who in who_all:
                env = dict(os.environ, BENCH_PLANNER_TREE=trees.get(who, trees["ours"]))
                proc = subprocess.run(
                    [sys.executable, str(here), "--child", who, "--cases", f"{kind}:{n}",
                     "--reps", str(args.reps)], capture_output=True, text=True, env=env,
                    timeout=args.timeout)
                if proc.returncode != 0:
                    print(f"{who} failed on map {kind} at {n}:\n{proc.stderr[-2000:]}", flush=True)
                    continue
                res[who] = json.loads(proc.stdout.strip().splitlines()[-1])
                r = res[who]
                med = statistics.median(r["times"])
                ratio = "-"
                if who != "ours" and "ours" in res:
                    ratio = _ratio(med, statistics.median(res["ours"]["times"]))
                rows.append([str(kind), str(n), who, _fmt(min(r["times"])), _fmt(med),
                             _fmt(max(r["times"])), "yes" if r["found"] else "none",
                             f"{r['rss_peak']:.0f}", f"{r['rss_peak'] - r['rss_before']:.0f}", ratio,
                             f"{os.getloadavg()[0]:.2f}"])
                print("  ".join(rows[-1]), flush=True)
    print()
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for row in rows:
        print("| " + " | ".join(row) + " |")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print a table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--oneshot", action="store_true", help="one-shot queries beside the peers "
                    "(min/median/max and memory, each contender in a fresh process)")
    ap.add_argument("--cases", default="2:5000,5:1000,5:2000,5:5000",
                    help="--oneshot: map:size pairs")
    ap.add_argument("--reps", type=int, default=3, help="--oneshot: queries per contender")
    ap.add_argument("--before", default=BEFORE_REV,
                    help="--oneshot: git revision whose find_path runs as 'before' ('' to skip)")
    ap.add_argument("--peers", default="tcod,pyastar2d", help="--oneshot: peers to run")
    ap.add_argument("--timeout", type=float, default=600.0, help="--oneshot: seconds per child")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--sizes", default="100,300,1000,2000,5000")
    ap.add_argument("--baseline-cap", type=float, default=30.0,
                    help="seconds before a baseline run is abandoned (shown as >cap)")
    ap.add_argument("--baseline-max", type=int, default=2000,
                    help="largest size the baseline runs at (its list-of-lists map alone "
                         "takes seconds to build at 5000)")
    ap.add_argument("--no-tcod", action="store_true")
    ap.add_argument("--markdown", action="store_true", help="print a markdown table")
    args = ap.parse_args(argv)
    if args.child:
        import json

        kind, n = (int(v) for v in args.cases.split(":"))
        print(json.dumps(_child(args.child, kind, n, args.reps)))
        return 0
    if args.oneshot:
        return oneshot(args)
    sizes = [int(s) for s in args.sizes.split(",") if s]

    t0 = time.perf_counter()
    from robo_comp.world import planner as pl
    t_import = time.perf_counter() - t0
    t_jit = pl.warm_up()
    print(f"import robo_comp.world.planner: {t_import * 1e3:.1f} ms; first-call JIT "
          f"(compile, or load from numba's on-disk cache): {t_jit:.2f} s", flush=True)
    from thesis_astar import thesis_astar

    tcod_path: Any = None
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

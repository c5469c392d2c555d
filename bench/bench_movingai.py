"""Run every Moving AI scenario under a maps directory, 8-connected, against the optimum.

For each ``X.map`` with an ``X.map.scen`` beside it, every scenario line (or the first
``--limit``) is solved with diagonal moves of cost √2 and no corner cutting. A cost counts
as a mismatch when it differs from the .scen optimum by more than 1e-3 relative (allowing
the 2-decimal rounding of older .scen files). Mean time per query is compared with
python-tcod's Pathfinder in the same run, configured to the same semantics: a CustomGraph
with cardinal edges 10000 and diagonal edges 14142 (√2 to 1e-5), each diagonal edge
allowed only from cells whose two orthogonal neighbours on that side are free (tcod's
``condition`` array), and the matching octile heuristic.

    .venv/bin/python bench/bench_movingai.py [--maps-dir ../shared/maps/movingai]
        [--limit N] [--no-tcod] [--hier] [--markdown]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

from robo_comp.world.maps import load_map, load_scen  # noqa: E402
from robo_comp.world.plan_cli import cost_matches  # noqa: E402

TCOD_CARD, TCOD_DIAG = 10000, 14142


def tcod_graph(walls: np.ndarray):
    """A tcod CustomGraph with our semantics (8-connected, √2, no corner cutting)."""
    import tcod.path

    h, w = walls.shape
    free = ~walls
    graph = tcod.path.CustomGraph((h, w))
    cost = free.astype(np.int32)
    padded = np.zeros((h + 2, w + 2), dtype=bool)
    padded[1:-1, 1:-1] = free
    for dy, dx in ((0, 1), (1, 0), (0, -1), (-1, 0)):
        graph.add_edge((dy, dx), TCOD_CARD, cost=cost)
    for dy, dx in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        vert = padded[1 + dy:h + 1 + dy, 1:w + 1]   # (y+dy, x) free
        horiz = padded[1:h + 1, 1 + dx:w + 1 + dx]  # (y, x+dx) free
        graph.add_edge((dy, dx), TCOD_DIAG, cost=cost, condition=(vert & horiz).astype(np.int8))
    graph.set_heuristic(cardinal=TCOD_CARD, diagonal=TCOD_DIAG)
    return graph


def tcod_query(graph, sx: int, sy: int, gx: int, gy: int) -> float | None:
    """Cost of tcod's path (None when none)."""
    import tcod.path

    pf = tcod.path.Pathfinder(graph)
    pf.add_root((sy, sx))
    path = pf.path_to((gy, gx))
    if len(path) == 0 or tuple(path[-1]) != (gy, gx) or tuple(path[0]) != (sy, sx):
        return None
    return float(pf.distance[gy, gx]) / TCOD_CARD


def uniform_sample(entries: list, n: int | None) -> list:
    """``n`` entries evenly spaced over ``entries`` (all of them when ``n`` is None or larger)."""
    if n is None or n >= len(entries):
        return list(entries)
    return [entries[int(i * len(entries) / n)] for i in range(n)]


def main(argv: list[str] | None = None) -> int:
    """Run the scenarios and print a table per map."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    here = Path(__file__).resolve().parent.parent
    ap.add_argument("--maps-dir", default=str(here.parent / "shared" / "maps" / "movingai"))
    ap.add_argument("--limit", type=int, default=None,
                    help="scenarios per map: an evenly spaced sample over the whole .scen (its lines run "
                         "from the shortest queries to the longest, so the first N would be the easiest)")
    ap.add_argument("--no-tcod", action="store_true")
    ap.add_argument("--hier", action="store_true", help="also run hierarchical mode")
    ap.add_argument("--markdown", action="store_true")
    args = ap.parse_args(argv)

    from robo_comp.world.planner import Planner, find_path, warm_up

    print(f"first-call JIT (compile or cache load): {warm_up():.2f} s", flush=True)
    maps = sorted(Path(args.maps_dir).glob("*/*.map"))
    if not maps:
        print(f"no .map files under {args.maps_dir}/*/", file=sys.stderr)
        return 2
    use_tcod = not args.no_tcod
    if use_tcod:
        try:
            import tcod.path  # noqa: F401
        except ImportError:
            print("tcod not installed: skipping it")
            use_tcod = False
    try:
        import pyastar2d
    except ImportError:
        pyastar2d = None
    head = ["map", "size", "queries", "mismatches", "ours ms/q", "tcod ms/q", "tcod mism.",
            "speed-up", "prep ms", "pyastar2d ms/q", "vs pyastar2d", "one-shot ms/q"]
    if args.hier:
        head += ["hier ms/q", "hier max/opt", "hier mean/opt"]
    rows = []
    tot_q = tot_mis = 0
    for mp in maps:
        scen = mp.with_name(mp.name + ".scen")
        if not scen.exists():
            continue
        gm = load_map(mp)
        entries = uniform_sample(load_scen(scen), args.limit)
        t0 = time.perf_counter()
        pl = Planner(gm.walls, diagonal=True).prepare()
        prep = time.perf_counter() - t0
        mis = 0
        t_ours = 0.0
        for e in entries:
            t0 = time.perf_counter()
            r = pl.find((e.sx, e.sy), (e.gx, e.gy))
            t_ours += time.perf_counter() - t0
            mis += not cost_matches(r.cost, e.optimal)
        row = [mp.parent.name + "/" + mp.name, f"{gm.width}x{gm.height}", str(len(entries)),
               str(mis), f"{t_ours / len(entries) * 1e3:.3f}"]
        if use_tcod:
            graph = tcod_graph(gm.walls)
            t_t = 0.0
            tmis = 0
            for e in entries:
                t0 = time.perf_counter()
                c = tcod_query(graph, e.sx, e.sy, e.gx, e.gy)
                t_t += time.perf_counter() - t0
                tmis += not cost_matches(c, e.optimal)
            row += [f"{t_t / len(entries) * 1e3:.3f}", str(tmis), f"{t_t / t_ours:.1f}x"]
        else:
            row += ["-", "-", "-"]
        row.append(f"{prep * 1e3:.1f}")
        if pyastar2d is not None:  # C++ A*; its diagonal moves cost 1 and may cut corners: a speed peer only
            weights = np.where(gm.walls, np.inf, 1.0).astype(np.float32)
            t_p = 0.0
            for e in entries:
                t0 = time.perf_counter()
                pyastar2d.astar_path(weights, (e.sy, e.sx), (e.gy, e.gx), allow_diagonal=True)
                t_p += time.perf_counter() - t0
            row += [f"{t_p / len(entries) * 1e3:.3f}", f"{t_p / t_ours:.2f}x"]
        else:
            row += ["-", "-"]
        few = entries[:: max(1, len(entries) // 20)]  # one-shot: a planner built per query (20 of them)
        t0 = time.perf_counter()
        for e in few:
            find_path(gm.walls, (e.sx, e.sy), (e.gx, e.gy), diagonal=True)
        row.append(f"{(time.perf_counter() - t0) / len(few) * 1e3:.3f}")
        if args.hier:
            ph = Planner(gm.walls, diagonal=True, hierarchical=True).prepare()
            t_h = 0.0
            ratios = []
            for e in entries:
                t0 = time.perf_counter()
                r = ph.find((e.sx, e.sy), (e.gx, e.gy))
                t_h += time.perf_counter() - t0
                if r.cost is not None and e.optimal > 0:
                    ratios.append(r.cost / e.optimal)
            row += [f"{t_h / len(entries) * 1e3:.3f}", f"{max(ratios, default=1):.4f}",
                    f"{(sum(ratios) / len(ratios)) if ratios else 1:.4f}"]
        tot_q += len(entries)
        tot_mis += mis
        rows.append(row)
        print("  ".join(row), flush=True)
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
    print(f"total: {tot_q} queries, {tot_mis} mismatches")
    return 1 if tot_mis else 0


if __name__ == "__main__":
    sys.exit(main())

"""``robo-comp plan``: plan a path on a map file, or check a Moving AI scenario file.

    robo-comp plan MAP START GOAL [--diagonal] [--json]
    robo-comp plan MAP --scen FILE [--limit N] [--json]

MAP is a Moving AI ``.map`` or a text grid; START and GOAL are ``x,y``. "No path" is a
normal answer (exit 0). Bad input prints one line on stderr and exits 2.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

from robo_comp.errors import ScenarioError


DESCRIPTION = "Plan a path on a map file, or check a Moving AI scenario file."


class _UsageError(Exception):
    pass


def add_parser(subparsers: Any) -> None:
    """Add the ``plan`` subcommand to an argparse subparsers object (sets ``func=run``)."""
    p = subparsers.add_parser("plan", help="plan a path on a map file (A*)",
                              description=DESCRIPTION)
    _configure(p)


def _configure(p: argparse.ArgumentParser) -> None:
    p.add_argument("map", metavar="MAP", help="Moving AI .map file, text grid, or a scenario (.toml, or a "
                                              "bundled scenario's name): its walls")
    p.add_argument("start", metavar="START", nargs="?", help="start cell as x,y")
    p.add_argument("goal", metavar="GOAL", nargs="?", help="goal cell as x,y")
    p.add_argument("--diagonal", action="store_true",
                   help="8-connected moves (diagonal cost √2, no corner cutting)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.add_argument("--scen", metavar="FILE", help="run a Moving AI .scen file (8-connected)")
    p.add_argument("--limit", type=int, metavar="N", help="run at most N scenario lines")
    p.set_defaults(func=run)


def _cell(text: str, what: str) -> tuple[int, int]:
    parts = text.split(",")
    try:
        if len(parts) != 2:
            raise ValueError
        return int(parts[0]), int(parts[1])
    except ValueError:
        raise _UsageError(f"{what} must be x,y (two integers), got {text!r}") from None


def run(args: argparse.Namespace) -> int:
    """Execute ``robo-comp plan``; returns the exit code."""
    try:
        return _run(args)
    except (ScenarioError, _UsageError) as exc:
        print(f"robo-comp plan: {exc}", file=sys.stderr)
        return 2


def _run(args: argparse.Namespace) -> int:
    from robo_comp.world.maps import GridMap, load_map

    if str(args.map).endswith(".toml") or "/" not in str(args.map) and "." not in str(args.map):
        from robo_comp.world.scenario import resolve_scenario
        from robo_comp.world.scenario import load_scenario

        sc = load_scenario(resolve_scenario(args.map))  # the scenario's walls (its map, extra walls)
        gm = GridMap(sc.walls, sc.name)
    else:
        gm = load_map(args.map)
    if args.scen:
        if args.start or args.goal:
            raise _UsageError("give either START GOAL or --scen, not both")
        return _run_scen(args, gm)
    if not args.start or not args.goal:
        raise _UsageError("START and GOAL are required (as x,y), or use --scen FILE")
    start = _cell(args.start, "START")
    goal = _cell(args.goal, "GOAL")
    for what, (x, y) in (("START", start), ("GOAL", goal)):
        if not (0 <= x < gm.width and 0 <= y < gm.height):
            raise _UsageError(f"{what} {x},{y} is outside the {gm.width}x{gm.height} map")
        if not gm.passable(x, y):
            raise _UsageError(f"{what} {x},{y} is a wall")
    from robo_comp.world.planner import Planner

    planner = Planner(gm.walls, diagonal=args.diagonal).prepare()
    _load_kernels()
    t0 = time.perf_counter()
    res = planner.find(start, goal)
    seconds = time.perf_counter() - t0
    if args.json:
        out = {"path": [list(c) for c in res.path] if res.path is not None else None,
               "cost": res.cost, "seconds": seconds}
        print(json.dumps(out))
    elif res.path is None:
        print(f"no path from {start[0]},{start[1]} to {goal[0]},{goal[1]}")
    else:
        print(f"cost {res.cost:.6g}, {len(res.path)} cells, {seconds * 1e3:.2f} ms")
        print(" ".join(f"{x},{y}" for x, y in res.path))
    return 0


def _run_scen(args: argparse.Namespace, gm: Any) -> int:
    from robo_comp.world.maps import load_scen
    from robo_comp.world.planner import Planner

    entries = load_scen(args.scen)
    if args.limit is not None:
        if args.limit < 0:
            raise _UsageError("--limit must be >= 0")
        entries = entries[:args.limit]
    planner = Planner(gm.walls, diagonal=True).prepare()
    _load_kernels()
    mismatches = []
    total = 0.0
    for i, e in enumerate(entries):
        if (e.w, e.h) != (gm.width, gm.height):
            raise _UsageError(f"{args.scen}: entry {i + 1} is for a {e.w}x{e.h} map, "
                              f"but {args.map} is {gm.width}x{gm.height}")
        t0 = time.perf_counter()
        res = planner.find((e.sx, e.sy), (e.gx, e.gy))
        total += time.perf_counter() - t0
        if not cost_matches(res.cost, e.optimal):
            mismatches.append({"line": i + 2, "start": [e.sx, e.sy], "goal": [e.gx, e.gy],
                               "expected": e.optimal, "got": res.cost})
    mean = total / len(entries) if entries else 0.0
    if args.json:
        print(json.dumps({"queries": len(entries), "mismatches": mismatches,
                          "mean_seconds": mean}))
    else:
        for m in mismatches:
            print(f"line {m['line']}: {m['start']} -> {m['goal']}: expected "
                  f"{m['expected']}, got {m['got']}")
        print(f"{len(entries)} queries, {len(mismatches)} mismatches, "
              f"mean {mean * 1e3:.3f} ms/query")
    return 0


def _load_kernels() -> None:
    """Load the compiled kernels (one tiny search) so reported times are query times."""
    import numpy as np

    from robo_comp.world.planner import Planner

    Planner(np.zeros((1, 2), dtype=bool)).find((0, 0), (1, 0))


def cost_matches(cost: float | None, optimal: float) -> bool:
    """Whether a path cost equals a .scen optimal length: within 1e-3 relative, allowing
    for files that round the optimum to two decimals (older Moving AI sets do)."""
    if cost is None:
        return False
    return abs(cost - optimal) <= max(1e-3 * optimal, 0.006)


def main(argv: list[str] | None = None) -> int:
    """Stand-alone entry point: ``python -m robo_comp.world.plan_cli``."""
    p = argparse.ArgumentParser(prog="robo-comp plan", description=DESCRIPTION)
    _configure(p)
    args = p.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())

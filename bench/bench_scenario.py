"""The scenario-test figure of issue 8: a 5-minute match with 8 robots, in-process.

    .venv/bin/python bench/bench_scenario.py [--scenario office] [--robots 8] [--seconds 300] [--runs 3]

Each run builds a :class:`robo_comp.testing.Bench` (the seeded in-process arena, the team's
sandbox process), loads the template's explorer through the real sandbox and plays
``--seconds`` of simulated time with ``--robots`` robots of team red: every robot sweeps its band
of the map with ``explore`` and reports the victims its pictures show (``sweep_plan`` and
``report_seen``, as in ``tests/scenarios``). Printed per run: the wall time of the whole scenario
test (bench start, upload, match, close) and of the match alone, the simulated time played,
robot calls, pictures, finds and the score; then the worst run against the 10 s target.
"""
from __future__ import annotations

import argparse
import pathlib
import sys
import time
from collections import Counter

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from robo_comp.testing import Bench, report_seen, sweep_plan  # noqa: E402

EXPLORER = ROOT / "team_templates" / "extensions" / "explorer.py"
TARGET = 10.0


def one_run(scenario: str, robots: int, seconds: float, spacing: int, seed: int) -> dict:
    t0 = time.perf_counter()
    with Bench(scenario, "red", robots=robots, seed=seed) as bench:
        bench.load(EXPLORER)
        out = bench.run_match(sweep_plan(bench, spacing), seconds=seconds, on_done=report_seen(bench))
    total = time.perf_counter() - t0
    topics = Counter(e["topic"] for e in out.events)
    return {"total": total, "match": out.wall_seconds, "sim": out.events[-1]["t"], "calls": topics["robot.call"],
            "pictures": topics["picture"], "bumps": topics["robot.bump"], "finds": len(out.finds),
            "victims": len(out.victims), "score": out.score, "events": len(out.events)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="office", help="bundled name or file (default office)")
    ap.add_argument("--robots", type=int, default=8)
    ap.add_argument("--seconds", type=float, default=300.0, help="simulated match length")
    ap.add_argument("--spacing", type=int, default=3,
                    help="sweep grid spacing in cells (3: the robots have work for all 300 s)")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    print(f"scenario {a.scenario}, {a.robots} robots, {a.seconds:g} simulated s, explorer sweep "
          f"(spacing {a.spacing}), seed {a.seed}")
    rows = []
    for i in range(a.runs):
        r = one_run(a.scenario, a.robots, a.seconds, a.spacing, a.seed)
        rows.append(r)
        print(f"  run {i + 1}: wall {r['total']:.2f} s (match {r['match']:.2f} s) for {r['sim']:.1f} simulated s; "
              f"{r['calls']} robot calls, {r['pictures']} pictures, {r['bumps']} bumps, "
              f"{r['finds']} finds, {r['victims']} victims, score {r['score']:g}, {r['events']} events")
    worst = max(r["total"] for r in rows)
    same = len({(r["score"], r["events"], r["calls"]) for r in rows}) == 1
    print(f"worst wall time {worst:.2f} s vs target < {TARGET:g} s: {'OK' if worst < TARGET else 'MISSED'}; "
          f"runs identical (score, events, calls): {same}")
    return 0 if worst < TARGET and same else 1


if __name__ == "__main__":
    raise SystemExit(main())

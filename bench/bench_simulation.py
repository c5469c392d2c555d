"""Benchmark: simulate many robots with range sensors on the 512×512 bundled map.

Every robot drives random legs (turn, then drive 1..10 cells, free heading mode) and all
robots' range sensors (front/left/right/down) are read at 10 Hz; the arena steps at 10 Hz.
Prints, for each fleet size, the ratio of simulated seconds to wall-clock seconds (> 1
means faster than real time) on one core.

    .venv/bin/python bench/bench_simulation.py              # 1,000 and 10,000 robots, 10 s each
    .venv/bin/python bench/bench_simulation.py --seconds 2  # quicker
    .venv/bin/python bench/bench_simulation.py --robots 1000 5000
"""
from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import numpy as np  # noqa: E402

from robo_comp.world.arena import Arena  # noqa: E402
from robo_comp.world.scenario import bundled_scenario_path, load_scenario  # noqa: E402


def run(n: int, seconds: float, hz: float = 10.0, seed: int = 1) -> dict[str, float]:
    """Simulate ``n`` robots for ``seconds`` of match time; returns timing figures."""
    sc = load_scenario(bundled_scenario_path("big_rooms"))
    arena = Arena(sc, seed=seed, capacity=n)
    rng = np.random.default_rng(seed)
    free = np.argwhere(~arena.walls)                       # (y, x) of free cells
    pick = free[rng.choice(len(free), size=n, replace=False)]
    for i, (y, x) in enumerate(pick):
        arena.add_robot(f"r{i}", "red" if i % 2 else "blue", int(x), int(y), float(rng.uniform(0, 360)))
    w0 = time.perf_counter()
    arena.sense_all()                                      # loads the numba kernel (disk cache)
    warm = time.perf_counter() - w0
    dt = 1.0 / hz
    steps = int(round(seconds * hz))
    events = bumps = commands = 0
    t_cmd = t_step = t_sense = 0.0
    t0 = time.perf_counter()
    for _ in range(steps):
        a = time.perf_counter()
        for tag in arena.idle_tags():
            arena.command(tag, "turn", float(rng.uniform(-180, 180)))
            arena.command(tag, "forward", float(rng.uniform(1, 10)), append=True)
            commands += 1
        b = time.perf_counter()
        ev = arena.step(dt)
        c = time.perf_counter()
        tags, readings = arena.sense_all()
        d = time.perf_counter()
        events += len(ev)
        bumps += sum(1 for e in ev if e.kind == "bump")
        t_cmd += b - a
        t_step += c - b
        t_sense += d - c
    wall = time.perf_counter() - t0
    assert len(tags) == n and readings.front.shape == (n,)
    return {"robots": n, "sim_s": steps * dt, "wall_s": wall, "ratio": steps * dt / wall,
            "commands": commands, "events": events, "bumps": bumps,
            "warmup_s": warm, "cmd_s": t_cmd, "step_s": t_step, "sense_s": t_sense}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="simulated seconds per run (default 10)")
    ap.add_argument("--robots", type=int, nargs="+", default=[1000, 10000], help="fleet sizes")
    args = ap.parse_args(argv)
    print(f"512×512 map (big_rooms), sense + step at 10 Hz, {args.seconds:g} s simulated per run")
    ok = True
    for n in args.robots:
        r = run(n, args.seconds)
        print(f"{n:>6} robots: {r['sim_s']:.1f} s simulated in {r['wall_s']:.2f} s wall-clock "
              f"-> ratio {r['ratio']:.1f}x real time  (commands {r['cmd_s']:.2f} s, step {r['step_s']:.2f} s, "
              f"sense {r['sense_s']:.2f} s; {r['commands']} commands, {r['bumps']} bumps; "
              f"warm-up {r['warmup_s']:.2f} s not counted)")
        if n <= 1000 and r["ratio"] <= 1.0:
            ok = False
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())

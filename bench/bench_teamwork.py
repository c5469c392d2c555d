"""Issue 33's figures: robots that work as a team, measured on the engine (and one live).

    .venv/bin/python bench/bench_teamwork.py [--bumps] [--end-error] [--takeover] [--baseline REV]
        [--seconds 120] [--scenarios demo_room,office,big_rooms] [--goto 200]

* ``--bumps``: bumps between teammates in league matches on the bundled scenarios, every team the
  league has (the team template's ``play`` and the four reference teams) playing once or more
  (pairs below), 4 robots a team (2 on demo_room, the scenario's count). A bump between teammates
  is a ``robot.bump`` whose ``with`` is a robot of the bumping robot's own team. Target: 0.
* ``--end-error``: ``goTo`` under noisy positioning (the office with positioning noise σ 0.5
  cells, 20 % of fixes lost, and a stop in the middle of a turn before every other ``goTo``, the
  issue's case; ``--drive free`` for robots that drive any heading and distance): per ``goTo`` the distance between the robot's *true* pose and the goal at the
  end (what the arena knows) and the end error the task reported; p50/p95/max against the
  tolerance (``robo_comp.robots.builtin_tasks.END_TOLERANCE``).
* ``--takeover``: a real core, two robot hosts of one team (real processes: one robot, and two
  idle teammates), reallocation on, the first host killed (SIGKILL) while its robot runs a
  ``goTo`` with a task queued behind it; the time from ``robot.lost`` to a teammate's
  ``task.started`` of the moved *queued* task (the core's log stamps), against the heartbeat.

``--baseline REV`` also runs ``--bumps`` on git revision REV's ``robo_comp`` (exported to a temporary
folder, a child process), in the same run. The machine's load (``uptime``) is printed with each
figure.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time
from typing import Any

ROOT = pathlib.Path(__file__).resolve().parent.parent
if "--tree" not in sys.argv:
    sys.path.insert(0, str(ROOT))

#: (team A, team B) per match: every team of the league plays on every scenario.
PAIRS = (("template", "explorer"), ("frontier", "random_walker"), ("sitter", "template"))
ROBOTS = {"demo_room": 2}


def uptime() -> str:
    """The machine's load, as ``uptime`` prints it."""
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def team_files(name: str, tree: pathlib.Path) -> dict[str, str]:
    """The files a league entrant ``name`` submits (the template's play, or a reference team)."""
    if name == "template":
        return {"play.py": (tree / "robo_comp/teams/template/extensions/play.py").read_text()}
    return {f"{name}.py": (tree / f"robo_comp/league/reference/{name}.py").read_text()}


def teammate_bumps(log: pathlib.Path) -> dict[str, int]:
    """Bumps between teammates per team in a core-format event log."""
    from robo_comp.protocol.logfile import read_log

    team_of: dict[int, str] = {}
    out: dict[str, int] = {}
    for rec in read_log(log, strict=False):
        d = rec.data
        if rec.topic == "robot.registered":
            team_of[d["tag"]] = d["team"]
        elif rec.topic == "robot.bump":
            team = team_of.get(d.get("tag"))
            if team is not None:
                out.setdefault(team, 0)
                if team_of.get(d.get("with")) == team:
                    out[team] += 1
    return out


def bumps_run(tree: pathlib.Path, scenarios: list[str], seconds: float, seed: int) -> list[dict[str, Any]]:
    """Every pair on every scenario: per team, bumps between teammates and all its bumps."""
    from robo_comp.league.engine import play_match

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for sc in scenarios:
            for a, b in PAIRS:
                log = pathlib.Path(tmp) / f"{sc}-{a}-{b}.log"
                spec = {"id": f"{sc}:{a}-{b}", "scenario": sc, "seed": seed, "seconds": seconds,
                        "robots": ROBOTS.get(sc, 4), "log": str(log), "timeout": 1200,
                        "entrants": [{"team": a, "version": "1", "files": team_files(a, tree)},
                                     {"team": b + ("2" if b == a else ""), "version": "1",
                                      "files": team_files(b, tree)}]}
                t0 = time.perf_counter()
                res = play_match(spec)
                mates = teammate_bumps(log)
                for team in (a, b):
                    rows.append({"scenario": sc, "team": team, "mates": mates.get(team, 0),
                                 "bumps": res["bumps"].get(team, 0), "score": res["scores"].get(team),
                                 "wall": round(time.perf_counter() - t0, 1)})
    return rows


def print_bumps(label: str, rows: list[dict[str, Any]]) -> None:
    print(f"  {label}: bumps between teammates {sum(r['mates'] for r in rows)} in all "
          f"({sum(r['bumps'] for r in rows)} bumps of any kind)")
    for r in rows:
        print(f"    {r['scenario']:<10} {r['team']:<14} teammates {r['mates']:>3}  all bumps {r['bumps']:>3}  "
              f"score {r['score']:g}")


def bumps(a: argparse.Namespace) -> None:
    scenarios = a.scenarios.split(",")
    print(f"bumps between teammates: {', '.join(scenarios)}, {a.seconds:g} simulated s a match, pairs "
          f"{', '.join('-'.join(p) for p in PAIRS)}; load: {uptime()}")
    if a.baseline:
        with tempfile.TemporaryDirectory() as tmp:
            old = pathlib.Path(tmp) / "baseline"
            old.mkdir()
            archive = subprocess.run(["git", "-C", str(ROOT), "archive", a.baseline, "robo_comp"],
                                     capture_output=True, check=True).stdout
            subprocess.run(["tar", "-x", "-C", str(old)], input=archive, check=True)
            env = dict(os.environ, PYTHONPATH=str(old))
            out = subprocess.run([sys.executable, __file__, "--tree", str(old), "--scenarios", a.scenarios,
                                  "--seconds", str(a.seconds), "--seed", str(a.seed)],
                                 capture_output=True, text=True, env=env, cwd=str(old), timeout=7200)
            if out.returncode != 0:
                print(f"  before ({a.baseline}): the run failed: {out.stderr[-2000:]}")
            else:
                print_bumps(f"before ({a.baseline})", json.loads(out.stdout.strip().splitlines()[-1]))
    print_bumps("this tree", bumps_run(ROOT, scenarios, a.seconds, a.seed))
    print(f"  load after: {uptime()}")


def end_error(a: argparse.Namespace) -> None:
    import dataclasses

    from robo_comp.engine.bench import Bench
    from robo_comp.robots.builtin_tasks import END_TOLERANCE
    from robo_comp.world.scenario import load_scenario, resolve_scenario

    sc = load_scenario(resolve_scenario("office"))
    noisy = dataclasses.replace(sc, positioning=dataclasses.replace(sc.positioning, noise=0.5, dropout=0.2),
                                kinematics=dataclasses.replace(sc.kinematics, drive=a.drive))
    print(f"goTo end error: office ({a.drive} driving), positioning noise σ {noisy.positioning.noise} cells, "
          f"{noisy.positioning.dropout:.0%} of fixes lost, a stop mid-turn before every other goTo, "
          f"{a.goto} goTos on 4 robots; tolerance {END_TOLERANCE} cells; load: {uptime()}")
    import random

    rng = random.Random(a.seed)
    truth: list[float] = []
    said: list[float] = []
    failed: dict[str, int] = {}
    with Bench(noisy, "red", robots=4, seed=a.seed, max_sim_seconds=60.0) as bench:
        free = [(x, y) for y in range(sc.height) for x in range(sc.width) if not bench.walls[y, x]]
        n = 0
        while n < a.goto:
            for tag in bench.tags:
                if n % 2 == 0:  # the case: a turn stopped half-way
                    r = bench.by_tag[tag]
                    bench.arena.command(r.robot_id, "turn", 90.0)
                    bench.arena.step(0.45)
                    r.driver.halt()
                    bench.loc.update()
                gx, gy = rng.choice(free)
                out = bench.run_match({tag: [("goTo", [gx, gy])]}, seconds=120.0)
                done = out.outcomes.get(tag) or []
                n += 1
                d = done[-1] if done else None
                if d is None or not d["ok"]:
                    why = "did not end in 120 s" if d is None else d["status"].split(" at (")[0].split(" after ")[0]
                    why = why.split(" (")[0][:60]
                    failed[why] = failed.get(why, 0) + 1
                    continue
                p = bench.arena.pose(bench.by_tag[tag].robot_id)
                truth.append(math.hypot(p.x - gx, p.y - gy))
                said.append(float(d["result"]["end_error"]))
    truth.sort()
    said.sort()

    def pct(v: list[float], q: float) -> float:
        return v[min(len(v) - 1, int(q * len(v)))] if v else float("nan")

    print(f"  {len(truth)} of {a.goto} goTos done; failed: {failed or 'none'}")
    print(f"  true distance from the goal at the end of a done goTo: p50 {pct(truth, .5):.3f}  p95 {pct(truth, .95):.3f}  "
          f"max {max(truth, default=float('nan')):.3f} cells")
    print(f"  end error the task reported:                        p50 {pct(said, .5):.3f}  p95 {pct(said, .95):.3f}  "
          f"max {max(said, default=float('nan')):.3f} cells")
    print(f"  p95 true end error {'below' if pct(truth, .95) < END_TOLERANCE else 'NOT below'} the tolerance "
          f"{END_TOLERANCE}; load after: {uptime()}")


def takeover(a: argparse.Namespace) -> None:
    from robo_comp.testing.match import start_match, wait_for, wait_robots

    print(f"lost robot's work: real core (heartbeat {a.heartbeat} s), two hosts of team red (one robot, two idle "
          f"teammates), the first killed mid-goTo; {a.reps} runs; load: {uptime()}")
    delays = []
    for rep in range(a.reps):
        with tempfile.TemporaryDirectory() as tmp:
            with start_match(pathlib.Path(tmp), "office", heartbeat=a.heartbeat) as m:
                red = m.client("red")
                red.request("teamwork", reallocate=True)
                victim = m.robots("red", 1, "--prefix", "doomed", "--speed", "1")
                wait_robots(red, 1)
                m.robots("red", 2, "--prefix", "mate", "--speed", "1")
                rows = wait_robots(red, 3)
                doomed = next(r for r in rows if r["robot_id"] == "doomed-1")
                red.request("give", tag=doomed["tag"], task="goTo", args=[40, 30])
                given = red.request("give", tag=doomed["tag"], task="goTo", args=[10, 23], queue=True)
                wait_for(lambda: any(e["data"].get("tag") == doomed["tag"] for e in m.logged_events("task.started")),
                         10, "the goTo to start")
                time.sleep(0.5)
                victim.kill()
                victim.wait()

                def started() -> float | None:
                    lost = [e for e in m.logged_events("robot.lost") if e["data"]["tag"] == doomed["tag"]]
                    moved = [e for e in m.logged_events("task.given")
                             if (e["data"].get("from") or {}).get("task_id") == given["task_id"]]
                    if not lost or not moved:
                        return None
                    begun = [e for e in m.logged_events("task.started") if e["data"]["task_id"] == moved[0]["data"]["task_id"]]
                    return begun[0]["t"] - lost[0]["t"] if begun else None
                d = wait_for(started, 30, "the teammate to start the moved task")
                delays.append(d * 1000)
                print(f"  run {rep + 1}: the queued goTo started on the teammate {d * 1000:.1f} ms after robot.lost")
    print(f"  median {statistics.median(delays):.1f} ms, max {max(delays):.1f} ms; one heartbeat = "
          f"{a.heartbeat * 1000:.0f} ms; load after: {uptime()}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bumps", action="store_true")
    ap.add_argument("--end-error", action="store_true")
    ap.add_argument("--takeover", action="store_true")
    ap.add_argument("--scenarios", default="demo_room,office,big_rooms")
    ap.add_argument("--seconds", type=float, default=120.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--goto", type=int, default=200)
    ap.add_argument("--drive", choices=("grid4", "free"), default="grid4",
                    help="--end-error: how the robots drive (grid4, the office's; free: any heading and distance)")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--heartbeat", type=float, default=0.5)
    ap.add_argument("--baseline", default="", help="git revision to measure --bumps on as well ('' to skip)")
    ap.add_argument("--tree", help=argparse.SUPPRESS)  # child mode: --bumps on this tree, JSON out
    a = ap.parse_args()
    if a.tree:
        print(json.dumps(bumps_run(pathlib.Path(a.tree), a.scenarios.split(","), a.seconds, a.seed)))
        return 0
    if not (a.bumps or a.end_error or a.takeover):
        a.bumps = a.end_error = a.takeover = True
    if a.bumps:
        bumps(a)
    if a.end_error:
        end_error(a)
    if a.takeover:
        takeover(a)
    return 0


if __name__ == "__main__":
    sys.exit(main())

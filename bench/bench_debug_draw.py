"""What debug drawing costs a league match (issue 29): time and log size, both in one run.

    .venv/bin/python bench/bench_debug_draw.py [--reps 3] [--seconds 300] [--scenario office]

Two league matches of the league's engine (:func:`robo_comp.league.engine.play_match`, the
real sandbox, 4 robots a team): ``frontier`` against ``explorer`` (the reference teams), and
the same two teams with debug drawing at the documented bound: before every movement call each
robot draws a full frame (:data:`robo_comp.protocol.drawing.MAX_SHAPES` shapes: 6 lines, 6 dots,
4 texts of 12 characters, placed from a counter so that no two frames are the same and every
recording tick records every robot; no robot call, so that only the drawing is measured). The plain and the drawing match alternate
``--reps`` times (each in a fresh process, so no cache favours the second); reported: the
median wall time and CPU time (the match's process: the sandbox children run under bubblewrap and
their time does not reach ``RUSAGE_CHILDREN``) of each and their increase, the log size of each and its increase, and whether
the scores and every event but ``debug.draw`` are the same (drawing costs nothing in score or
simulated time). The load (``uptime``) is printed before and after. Exit 1 when either
increase is 5 % or more.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

#: Prepended to a reference team: a full frame of drawing, new every call.
DOODLE = '''
drawn_count = [0]


def doodle_frame(robot):
    drawn_count[0] = drawn_count[0] + 1
    k = drawn_count[0] % 97
    x = 2 + (drawn_count[0] * 7) % 30
    y = 2 + (drawn_count[0] * 3) % 20
    for i in range(LINES):
        robot.draw_line(x, y, x + (i - 3) * 0.5, y + 2 + k * 0.01, "cyan")
    for i in range(DOTS):
        robot.draw_dot(x + i - 3, y - 2 - k * 0.01, "red")
    for i in range(TEXTS):
        robot.draw_text(x + 1, y - 1 - i, "goal " + str(k) + ":" + str(i) + " ok", "yellow")
'''


def drawing(source: str, shapes: int = 16) -> str:
    """``source`` (a reference team) with a frame of ``shapes`` shapes (16: the bound; 6 lines,
    6 dots, 4 texts, the first ones of that order for fewer) drawn before each movement call."""
    lines, dots = min(shapes, 6), min(max(0, shapes - 6), 6)
    texts = max(0, shapes - 12)
    body = re.sub(r"\brobot\.(turn|move|go_to)\(", r"doodle_frame(robot) or robot.\1(", source)
    cut = body.index("\nMANIFEST")
    end = body.index("\n}\n", cut) + 3
    return (body[:end] + f"\nLINES = {lines}\nDOTS = {dots}\nTEXTS = {texts}\n" + DOODLE + body[end:])


def one(spec_path: str) -> None:
    """Child: play the match in ``spec_path`` and print its result as JSON."""
    from robo_comp.league.engine import play_match

    spec = json.loads(Path(spec_path).read_text())
    print(json.dumps(play_match(spec)))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=300.0)
    ap.add_argument("--scenario", default="office")
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--shapes", type=int, default=16, help="shapes a frame (default 16: the documented bound)")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        one(args.child)
        return 0
    from robo_comp.league import reference
    from robo_comp.protocol import drawing as D
    from robo_comp.protocol.logfile import read_log

    print("load before:", subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip(), flush=True)
    tmp = Path(tempfile.mkdtemp(prefix="bench_debug_draw_"))
    teams = {"frontier": reference.source("frontier"), "explorer": reference.source("explorer")}
    results: dict[str, list[dict]] = {"plain": [], "drawing": []}
    for rep in range(args.reps):
        for kind in ("plain", "drawing"):
            log = tmp / f"{kind}-{rep}.log"
            spec = {"id": rep, "scenario": args.scenario, "seed": args.seed, "seconds": args.seconds, "robots": 4,
                    "entrants": [{"team": t, "version": kind, "files": {"play.py": drawing(s, args.shapes) if kind == "drawing" else s}}
                                 for t, s in teams.items()], "log": str(log)}
            path = tmp / f"{kind}-{rep}.json"
            path.write_text(json.dumps(spec))
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            out = subprocess.run([sys.executable, __file__, "--child", str(path)], capture_output=True, text=True,
                                 env=dict(os.environ, PYTHONPATH=str(ROOT)))
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            if out.returncode:
                print(out.stderr[-3000:], file=sys.stderr)
                return 2
            r = json.loads(out.stdout.strip().splitlines()[-1])
            r["size"] = log.stat().st_size
            # CPU of the match's process (the sandboxes' does not reach RUSAGE_CHILDREN: bubblewrap): steadier than wall time on a loaded machine
            r["cpu"] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
            results[kind].append(r)
            print(f"rep {rep} {kind}: {r['wall_seconds']:.2f} s ({r['cpu']:.2f} s CPU), log {r['size']:,} bytes, scores {r['scores']}",
                  flush=True)
    plain, draw = results["plain"], results["drawing"]
    t_plain = statistics.median(r["wall_seconds"] for r in plain)
    t_draw = statistics.median(r["wall_seconds"] for r in draw)
    cpu_plain = statistics.median(r["cpu"] for r in plain)
    cpu_draw = statistics.median(r["cpu"] for r in draw)
    size_plain, size_draw = plain[0]["size"], draw[0]["size"]
    frames = [rec for rec in read_log(tmp / "drawing-0.log") if rec.topic == "debug.draw"]
    shapes = sum(len(f) for rec in frames for f in rec.data["frames"])
    same_scores = all(r["scores"] == plain[0]["scores"] for r in plain + draw)
    rest = [[(rec.topic, rec.team, rec.data) for rec in read_log(tmp / f"{k}-0.log") if rec.topic != "debug.draw"]
            for k in ("plain", "drawing")]
    print(f"\nmatch: {args.scenario}, {args.seconds:g} s, 4 robots a team, frontier vs explorer, seed {args.seed}; "
          f"{args.reps} reps each, alternating, fresh processes")
    print(f"drawn: {args.shapes} shapes a frame before every movement call; bound: {D.MAX_SHAPES} shapes a frame, one recording per robot per {D.TICK:g} s; the drawing match "
          f"recorded {len(frames)} debug.draw events, {shapes:,} shapes")
    print(f"time: plain {t_plain:.2f} s, drawing {t_draw:.2f} s (median): {100 * (t_draw / t_plain - 1):+.1f} %")
    print(f"CPU (the match process; not its sandboxes): plain {cpu_plain:.2f} s, drawing {cpu_draw:.2f} s (median): "
          f"{100 * (cpu_draw / cpu_plain - 1):+.1f} %")
    print(f"log size: plain {size_plain:,} bytes, drawing {size_draw:,} bytes: {100 * (size_draw / size_plain - 1):+.1f} %")
    print(f"scores the same in every match: {same_scores}; every other event the same: {rest[0] == rest[1]}")
    print("load after:", subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip())
    ok = t_draw / t_plain < 1.05 and size_draw / size_plain < 1.05
    print("target met (< 5 % each)" if ok else "target missed (5 % or more)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

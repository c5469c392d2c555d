"""Display-wall frame rate (issue 7): 1,000 robots moving, headless (SDL dummy driver).

    .venv/bin/python bench/bench_wall.py [--robots 1000] [--frames 120] [--no-trails] [--story]

Feeds the wall's model directly with a synthetic ``robot.positions`` batch per team per
frame (all robots move every frame, the worst case: the core sends 10 batches per second), then
times drawing and ``display.flip`` (incremental frames, as the wall's window does; ``--full``
redraws everything each frame, as screenshots do). Configurations: the whole 7168×3072 Tromsø wall in one
process, one 1024×768 tile of that wall as a 7×4 grid (the middle tile (3,1)), and one
1024×768 window showing the whole arena (all robots in view), beside its peer in the same run: a
bare pygame loop drawing as many circles. The legend is drawn (the wall's default); ``--story``
also gives the wall a story of 300 ticker lines, a new one every 10th frame (issue 29's ticker,
as a busy match tells it). Exit status 1 if the tile stays under 30 fps or the whole-arena
window under 60 fps.
"""
from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
import pygame  # noqa: E402

from robo_comp.view.model import MatchView  # noqa: E402
from robo_comp.wall.render import Overlay, Renderer  # noqa: E402
from robo_comp.wall.view import TileSpec, ViewState  # noqa: E402

TEAMS = [("red", "#d03030"), ("blue", "#3060d0"), ("green", "#30a040"), ("orange", "#e08020")]


def arena(w: int = 240, h: int = 100) -> dict:
    """Rooms of 20×20 cells with doors: a busy static map."""
    walls = np.zeros((h, w), bool)
    walls[0, :] = walls[-1, :] = walls[:, 0] = walls[:, -1] = True
    for x in range(20, w, 20):
        walls[:, x] = True
        walls[5:8, x] = walls[h // 2 + 5:h // 2 + 8, x] = False
    for y in range(20, h, 20):
        walls[y, :] = True
        for x in range(10, w, 20):
            walls[y, x - 1:x + 2] = False
    return {"name": "bench", "width": w, "height": h, "cell_cm": 25.0,
            "walls": np.packbits(walls, axis=None).tobytes(),
            "zones": [{"kind": "rubble", "x": 30, "y": 30, "w": 8, "h": 6},
                      {"kind": "water", "x": 100, "y": 60, "w": 12, "h": 9}],
            "objects": [], "teams": [{"name": n, "colour": c, "start": None} for n, c in TEAMS]}


def story(robots: int, lines: int) -> Any:
    """A story of ``lines`` finds and bumps (None without the story module: an older tree)."""
    try:
        from robo_comp.view.story import Story
    except ImportError:
        return None
    st = Story()
    for i in range(lines):
        tell(st, i, robots)
    return st


def tell(st: Any, i: int, robots: int) -> None:
    """One more line: a find or a bump of some robot, with its score line."""
    team, tag = TEAMS[i % 4][0], 101 + (i * 7) % robots
    if i % 3:
        st.apply("robot.bump", {"team": team, "tag": tag, "x": 5.0, "y": 5.0}, float(i), float(i))
        st.apply("score.change", {"team": team, "points": -1, "kind": "collision", "reason": "bump"},
                 float(i), float(i))
    else:
        st.apply("find.reported", {"team": team, "tag": tag, "x": 9.0, "y": 5.0, "kind": "adult", "state": "confirmed"},
                 float(i), float(i))
        st.apply("score.change", {"team": team, "points": 10, "kind": "victim", "reason": "victim found"},
                 float(i), float(i))


def run(tile: TileSpec, robots: int, frames: int, trails: bool, incremental: bool = True,
        lines: int = 0) -> dict[str, float]:
    """Frames per second for one configuration (``lines``: the ticker's story, 0 for none)."""
    pygame.display.init()
    pygame.font.init()
    screen = pygame.display.set_mode(tile.size)
    a = arena()
    model = MatchView()
    model.load_snapshot({"arena": a, "robots": [], "match": {"phase": "running", "elapsed": 0.0, "remaining": 600.0},
                         "score": [{"team": n, "score": 0, "victims": 0, "penalties": 0, "rank": i + 1}
                                   for i, (n, _) in enumerate(TEAMS)]})
    rng = np.random.default_rng(7)
    x = rng.uniform(1, a["width"] - 2, robots)
    y = rng.uniform(1, a["height"] - 2, robots)
    head = rng.uniform(0, 360, robots)
    tags = list(range(101, 101 + robots))
    for i, tag in enumerate(tags):
        if i % 50 == 0:
            model.apply("robot.lost", {"tag": tag, "team": TEAMS[i % 4][0], "x": x[i], "y": y[i]})
    renderer = Renderer(model, tile, ViewState(), trails=trails)
    st = story(robots, lines) if lines else None
    overlay = Overlay(story=st) if st is not None else None  # (an older tree's Overlay has no story)
    renderer.draw(screen, 0.0, overlay)  # the static map for this zoom level is built once, outside the timing
    feed, draw = [], []
    for f in range(frames + 5):
        head += rng.uniform(-20, 20, robots)
        rad = np.radians(head)
        x = np.clip(x + np.cos(rad) * 0.15, 1, a["width"] - 2)
        y = np.clip(y + np.sin(rad) * 0.15, 1, a["height"] - 2)
        t0 = time.perf_counter()
        apply = model.apply
        for k, (team, _) in enumerate(TEAMS):  # one conflated batch per team, as the core sends
            apply("robot.positions", {"team": team, "tags": tags[k::4], "x": x[k::4].tolist(),
                                      "y": y[k::4].tolist(), "heading": head[k::4].tolist(),
                                      "moving": [True] * len(tags[k::4])})
        if st is not None and f % 10 == 0:
            tell(st, lines + f, robots)
        t1 = time.perf_counter()
        renderer.draw(screen, f / 30, overlay, incremental=incremental)
        pygame.display.flip()
        t2 = time.perf_counter()
        if f >= 5:  # the first frames fill the trail caches
            feed.append(t1 - t0)
            draw.append(t2 - t1)
    pygame.display.quit()
    d = statistics.median(draw)
    return {"fps_draw": 1 / d, "fps_total": 1 / statistics.median([a + b for a, b in zip(feed, draw)]),
            "draw_ms": d * 1000, "feed_ms": statistics.median(feed) * 1000,
            "p95_draw_ms": sorted(draw)[math.ceil(len(draw) * 0.95) - 1] * 1000}


def bare_circles(robots: int, frames: int) -> float:
    """The peer: frames per second of a bare pygame loop that clears a 1024×768 window and draws
    ``robots`` filled circles (no map, no headings, no trails, no labels) and flips."""
    pygame.display.init()
    screen = pygame.display.set_mode((1024, 768))
    rng = np.random.default_rng(7)
    xs = rng.uniform(5, 1019, robots)
    ys = rng.uniform(5, 763, robots)
    times = []
    for _ in range(frames + 5):
        xs = np.clip(xs + rng.uniform(-1, 1, robots), 5, 1019)
        ys = np.clip(ys + rng.uniform(-1, 1, robots), 5, 763)
        t0 = time.perf_counter()
        screen.fill((240, 240, 240))
        for x, y in zip(xs.tolist(), ys.tolist()):
            pygame.draw.circle(screen, (200, 40, 40), (x, y), 4)
        pygame.display.flip()
        times.append(time.perf_counter() - t0)
    pygame.display.quit()
    return 1 / statistics.median(times[5:])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, default=1000)
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--no-trails", action="store_true")
    ap.add_argument("--full", action="store_true", help="redraw every frame whole (the wall restores only what changed)")
    ap.add_argument("--story", action="store_true", help="a ticker of 300 lines, a new line every 10th frame")
    args = ap.parse_args()
    configs = [("7168x3072 wall, one process", TileSpec(1, 1, 0, 0, 7168, 3072), max(20, args.frames // 4)),
               ("1024x768 tile (3,1) of a 7x4 wall", TileSpec(7, 4, 3, 1, 1024, 768), args.frames),
               ("1024x768 window, whole arena", TileSpec(1, 1, 0, 0, 1024, 768), args.frames)]
    print(f"{args.robots} robots moving every frame, trails {'off' if args.no_trails else 'on'}, "
          f"{'full' if args.full else 'incremental'} redraws, SDL dummy driver"
          + (", a ticker of 300 lines (a new one every 10th frame)" if args.story else ""))
    print(f"{'configuration':<36} {'fps (draw+flip)':>16} {'draw ms':>8} {'p95 ms':>7} {'feed ms':>8} "
          f"{'fps incl. feed':>15}")
    tile_fps = whole_fps = 0.0
    for name, tile, frames in configs:
        r = run(tile, args.robots, frames, not args.no_trails, not args.full, 300 if args.story else 0)
        print(f"{name:<36} {r['fps_draw']:>16.1f} {r['draw_ms']:>8.2f} {r['p95_draw_ms']:>7.2f} "
              f"{r['feed_ms']:>8.2f} {r['fps_total']:>15.1f}", flush=True)
        if "tile" in name:
            tile_fps = r["fps_draw"]
        if "whole arena" in name:
            whole_fps = r["fps_total"]
    bare = bare_circles(args.robots, args.frames)
    print(f"peer, same run: a bare pygame loop drawing {args.robots} circles in a 1024x768 window: {bare:.1f} fps")
    ok = tile_fps >= 30 and whole_fps >= 60
    print(f"one 1024x768 tile: {tile_fps:.1f} fps (target 30); one 1024x768 window with all {args.robots} robots: "
          f"{whole_fps:.1f} fps including the feed = {whole_fps / bare:.0%} of the bare loop (target 60 fps): "
          f"{'met' if ok else 'MISSED'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

"""Match results: ``results.json``, ``results.csv`` and a score-over-time plot ``scores.png``."""
from __future__ import annotations

import csv
import json
import os
from pathlib import Path
from typing import Any

PLOT_SIZE = (800, 400)
_COLOURS = [(214, 39, 40), (31, 119, 180), (44, 160, 44), (255, 127, 14), (148, 103, 189), (140, 86, 75)]


def write_results(folder: Path, scores: dict[str, Any], lines: list[dict[str, Any]],
                  finds: list[dict[str, Any]]) -> dict[str, Any]:
    """Write the three result files; return the JSON document."""
    folder.mkdir(parents=True, exist_ok=True)
    doc = {"format": "robo_comp-results", "version": 1, "match": {k: scores.get(k) for k in
           ("phase", "elapsed", "remaining", "duration")}, "ranking": scores["teams"],
           "scoring": scores.get("scoring"), "changes": lines, "finds": finds}
    tmp = folder / "results.json.tmp"
    tmp.write_text(json.dumps(doc, indent=2, default=str))
    os.replace(tmp, folder / "results.json")
    with open(folder / "results.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["rank", "team", "score", "victims", "penalties", "disqualified"])
        for r in scores["teams"]:
            w.writerow([r["rank"], r["team"], r["score"], r["victims"], r["penalties"], r["disqualified"]])
    plot_scores(folder / "scores.png", [r["team"] for r in scores["teams"]], lines,
                float(scores.get("elapsed") or 0.0))
    return doc


def score_series(teams: list[str], lines: list[dict[str, Any]]) -> dict[str, list[tuple[float, float]]]:
    """Cumulative score over match time per team, as step points ``(t, score)``."""
    series = {t: [(0.0, 0.0)] for t in teams}
    totals = dict.fromkeys(teams, 0.0)
    for ln in sorted(lines, key=lambda ln: ln["t"]):
        if ln["team"] in totals:
            totals[ln["team"]] += ln["points"]
            series[ln["team"]].append((ln["t"], totals[ln["team"]]))
    return series


def plot_scores(path: Path, teams: list[str], lines: list[dict[str, Any]], end: float) -> None:
    """Draw the score-over-time plot as a PNG with pygame (no display needed)."""
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    import pygame

    pygame.font.init()
    w, h = PLOT_SIZE
    left, right, top, bottom = 60, 140, 20, 40
    surf = pygame.Surface((w, h))
    surf.fill((255, 255, 255))
    series = score_series(teams, lines)
    t_max = max([end, 1.0] + [p[0] for s in series.values() for p in s])
    values = [p[1] for s in series.values() for p in s]
    lo, hi = min(values + [0.0]), max(values + [1.0])
    span = hi - lo or 1.0

    def xy(t: float, v: float) -> tuple[int, int]:
        return (left + int((w - left - right) * t / t_max), top + int((h - top - bottom) * (hi - v) / span))

    font = pygame.font.Font(None, 20)
    pygame.draw.line(surf, (0, 0, 0), xy(0, lo), xy(t_max, lo))
    pygame.draw.line(surf, (0, 0, 0), xy(0, lo), xy(0, hi))
    pygame.draw.line(surf, (180, 180, 180), xy(0, 0), xy(t_max, 0))
    for v in (lo, 0.0, hi):
        surf.blit(font.render(f"{v:g}", True, (0, 0, 0)), (5, xy(0, v)[1] - 7))
    surf.blit(font.render(f"{t_max:.0f} s", True, (0, 0, 0)), (xy(t_max, lo)[0] - 20, h - bottom + 8))
    for i, team in enumerate(teams):
        colour = _COLOURS[i % len(_COLOURS)]
        pts = series[team] + [(t_max, series[team][-1][1])]
        steps = []
        for (t0, v0), (t1, _) in zip(pts, pts[1:]):
            steps += [xy(t0, v0), xy(t1, v0)]
        if len(steps) >= 2:
            pygame.draw.lines(surf, colour, False, steps, 3)
        surf.blit(font.render(f"{team} {pts[-1][1]:g}", True, colour), (w - right + 10, top + 22 * i))
    pygame.image.save(surf, str(path))

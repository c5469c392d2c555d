"""Match results: ``results.json``, ``results.csv`` and a score-over-time plot ``scores.png``."""
from __future__ import annotations

import colorsys
import csv
import json
import os
from pathlib import Path
from typing import Any

PLOT_SIZE = (800, 400)
_COLOURS = [(214, 39, 40), (31, 119, 180), (44, 160, 44), (255, 127, 14), (148, 103, 189), (140, 86, 75)]
RGB = tuple[int, int, int]


def team_palette(n: int) -> list[RGB]:
    """``n`` colours that differ: the six above, then hues spread evenly (never a repeat)."""
    out = list(_COLOURS[:n])
    extra = n - len(out)
    for i in range(extra):
        r, g, b = colorsys.hsv_to_rgb((i / max(1, extra) + 0.08) % 1.0, 0.75, 0.8 if i % 2 else 0.6)
        out.append((int(r * 255), int(g * 255), int(b * 255)))
    return out


def team_colours(teams: list[str], given: dict[str, RGB] | None = None) -> dict[str, RGB]:
    """A colour per team: its own (the scenario's) where given, else one of :func:`team_palette`
    by the team's place in name order, so a team keeps its colour whatever its rank."""
    given = dict(given or {})
    rest = sorted(t for t in teams if t not in given)
    return {**dict(zip(rest, team_palette(len(rest)))), **{t: c for t, c in given.items() if t in teams}}


def write_results(folder: Path, scores: dict[str, Any], lines: list[dict[str, Any]],
                  finds: list[dict[str, Any]], colours: dict[str, RGB] | None = None) -> dict[str, Any]:
    """Write the three result files; return the JSON document. ``colours``: the teams' own
    colours (the scenario's) for the plot."""
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
                float(scores.get("elapsed") or 0.0), colours)
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


def plot_scores(path: Path, teams: list[str], lines: list[dict[str, Any]], end: float,
                colours: dict[str, RGB] | None = None) -> None:
    """Draw the score-over-time plot as a PNG with pygame (no display needed): a title, labelled
    axes with ticks, a line per team in the team's own colour (:func:`team_colours`) and a legend
    in ranking order (``teams``)."""
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    import pygame

    pygame.font.init()
    w, h = PLOT_SIZE
    left, right, top, bottom = 70, 150, 40, 50
    colour_of = team_colours(teams, colours)
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
    big = pygame.font.Font(None, 28)
    ink, grid = (0, 0, 0), (225, 225, 225)
    for k in range(6):  # time ticks and grid
        t = t_max * k / 5
        x, y = xy(t, lo)
        pygame.draw.line(surf, grid, (x, top), (x, y))
        label = font.render(f"{t:.0f}", True, ink)
        surf.blit(label, (x - label.get_width() // 2, y + 6))
    for v in sorted({lo, 0.0, hi, round(lo + span / 2, 1)}):  # score ticks
        y = xy(0, v)[1]
        pygame.draw.line(surf, grid if v else (160, 160, 160), (left, y), (w - right, y))
        label = font.render(f"{v:g}", True, ink)
        surf.blit(label, (left - 8 - label.get_width(), y - 7))
    pygame.draw.line(surf, ink, xy(0, lo), xy(t_max, lo))
    pygame.draw.line(surf, ink, xy(0, lo), xy(0, hi))
    title = big.render("Score over time", True, ink)
    surf.blit(title, ((w - right + left) // 2 - title.get_width() // 2, 10))
    xl = font.render("match time (s)", True, ink)
    surf.blit(xl, ((w - right + left) // 2 - xl.get_width() // 2, h - 22))
    yl = pygame.transform.rotate(font.render("points", True, ink), 90)
    surf.blit(yl, (8, (h - bottom + top) // 2 - yl.get_height() // 2))
    for i, team in enumerate(teams):
        colour = colour_of[team]
        pts = series[team] + [(t_max, series[team][-1][1])]
        steps = []
        for (t0, v0), (t1, _) in zip(pts, pts[1:]):
            steps += [xy(t0, v0), xy(t1, v0)]
        if len(steps) >= 2:
            pygame.draw.lines(surf, colour, False, steps, 3)
        surf.blit(font.render(f"{team} {pts[-1][1]:g}", True, colour), (w - right + 10, top + 22 * i))
    pygame.image.save(surf, str(path))

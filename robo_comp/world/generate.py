"""Procedurally generated scenarios: rooms, corridors, rubble and victims from a seed.

``generate_scenario(seed, difficulty=0.5)`` returns a scenario file's text (TOML with the map
inline), the same text for the same arguments. The layout is a grid of rooms cut by recursive
division, joined through doorways; a central corridor runs from one side to the other. The
difficulty knob (0..1) makes rooms smaller and doors narrower, adds rubble and blocked cells,
and puts more victims further from the starts, behind more doors.

Always solvable: every victim's cell and every team's start zone can be reached from every
start zone (checked by a breadth-first search; a failing layout gets more doorways until it
holds). ``robo-comp scenario generate --seed N`` writes one.
"""
from __future__ import annotations

import random
from collections import deque
from pathlib import Path

import numpy as np

from robo_comp.errors import FieldError

#: Team colours and start corners in slot order: west, east, north-west, south-east, ...
_TEAMS = (("red", "red"), ("blue", "blue"), ("green", "green"), ("yellow", "yellow"))
KINDS = ("adult", "adult", "child", "injured")
MIN_W, MIN_H = 24, 16


def _divide(walls: np.ndarray, x0: int, y0: int, x1: int, y1: int, min_room: int, door: int,
            rng: random.Random, depth: int = 0) -> None:
    """Recursive division of the free box [x0, x1) × [y0, y1) into rooms joined by doors."""
    w, h = x1 - x0, y1 - y0
    if w < 2 * min_room + 1 and h < 2 * min_room + 1:
        return
    vertical = w >= h if w != h else rng.random() < 0.5
    if vertical and w >= 2 * min_room + 1:
        x = rng.randrange(x0 + min_room, x1 - min_room)
        walls[y0:y1, x] = True
        for _ in range(1 + (h > 12 and rng.random() < 0.5)):
            d = rng.randrange(y0, max(y0 + 1, y1 - door + 1))
            walls[d:d + door, x] = False
        _divide(walls, x0, y0, x, y1, min_room, door, rng, depth + 1)
        _divide(walls, x + 1, y0, x1, y1, min_room, door, rng, depth + 1)
    elif h >= 2 * min_room + 1:
        y = rng.randrange(y0 + min_room, y1 - min_room)
        walls[y, x0:x1] = True
        for _ in range(1 + (w > 12 and rng.random() < 0.5)):
            d = rng.randrange(x0, max(x0 + 1, x1 - door + 1))
            walls[y, d:d + door] = False
        _divide(walls, x0, y0, x1, y, min_room, door, rng, depth + 1)
        _divide(walls, x0, y + 1, x1, y1, min_room, door, rng, depth + 1)


def reachable(walls: np.ndarray, starts: list[tuple[int, int]]) -> np.ndarray:
    """Cells reachable (4-connected) from any of ``starts``: a bool grid like ``walls``."""
    h, w = walls.shape
    seen = np.zeros_like(walls, dtype=bool)
    q: deque[tuple[int, int]] = deque()
    for x, y in starts:
        if not walls[y, x] and not seen[y, x]:
            seen[y, x] = True
            q.append((x, y))
    while q:
        x, y = q.popleft()
        for nx, ny in ((x + 1, y), (x - 1, y), (x, y + 1), (x, y - 1)):
            if 0 <= nx < w and 0 <= ny < h and not walls[ny, nx] and not seen[ny, nx]:
                seen[ny, nx] = True
                q.append((nx, ny))
    return seen


def _distances(walls: np.ndarray, start: tuple[int, int]) -> np.ndarray:
    h, w = walls.shape
    dist = np.full(walls.shape, -1, dtype=np.int32)
    dist[start[1], start[0]] = 0
    q = deque([start])
    while q:
        x, y = q.popleft()
        for nx, ny in ((x + 1, y), (x - 1, y), (x, y + 1), (x, y - 1)):
            if 0 <= nx < w and 0 <= ny < h and not walls[ny, nx] and dist[ny, nx] < 0:
                dist[ny, nx] = dist[y, x] + 1
                q.append((nx, ny))
    return dist


def _start_rects(width: int, height: int, teams: int) -> list[tuple[int, int, int, int]]:
    """Start zones (x, y, w, h): west and east ends of the corridor, then the corners."""
    cy = height // 2 - 2
    rects = [(1, cy, 3, 4), (width - 4, cy, 3, 4), (1, 1, 3, 3), (width - 4, height - 4, 3, 3)]
    return rects[:teams]


def generate_scenario(seed: int, *, difficulty: float = 0.5, width: int = 64, height: int = 48,
                      teams: int = 2, robots: int = 4) -> str:
    """A solvable scenario (TOML text) generated from ``seed``; see the module docstring."""
    if not 0.0 <= difficulty <= 1.0:
        raise FieldError(f"difficulty must be between 0 and 1, not {difficulty:g}")
    if width < MIN_W or height < MIN_H or width > 1024 or height > 1024:
        raise FieldError(f"the size must be from {MIN_W}x{MIN_H} to 1024x1024 cells, not {width}x{height}")
    if not 1 <= teams <= len(_TEAMS):
        raise FieldError(f"a generated scenario has start zones for 1 to {len(_TEAMS)} teams, not {teams}")
    if not 1 <= robots <= 9:
        raise FieldError(f"a generated scenario's start zone holds 1 to 9 robots, not {robots}")
    rng = random.Random(f"robo_comp-generate:{seed}:{difficulty:.4f}:{width}x{height}:{teams}")
    walls = np.zeros((height, width), dtype=bool)
    walls[0, :] = walls[-1, :] = True
    walls[:, 0] = walls[:, -1] = True
    min_room = max(3, round(8 - 4 * difficulty))
    door = 1 if difficulty >= 0.6 else 2
    _divide(walls, 1, 1, width - 1, height - 1, min_room, door, rng)
    cy = height // 2 - 2
    corridor = (cy, cy + 4) if difficulty < 0.4 else (cy + 1, cy + 3)
    walls[corridor[0]:corridor[1], 1:width - 1] = False  # the main corridor, start to start
    starts = _start_rects(width, height, teams)
    for x, y, w, h in starts:
        walls[y:y + h, x:x + w] = False
    # blocked cells (fallen furniture) inside rooms, more with difficulty
    for _ in range(int(width * height * 0.01 * difficulty)):
        x, y = rng.randrange(2, width - 2), rng.randrange(2, height - 2)
        if not any(sx - 1 <= x <= sx + w and sy - 1 <= y <= sy + h for sx, sy, w, h in starts):
            walls[y, x] = True
    start_cells = [(x, y) for sx, sy, w, h in starts for x in range(sx, sx + w) for y in range(sy, sy + h)]
    _connect(walls, start_cells, rng)
    free = reachable(walls, start_cells[:1])
    # victims: far from the starts, more and further with difficulty
    dist = _distances(walls, start_cells[0])
    for sx, sy, _, _ in starts[1:]:
        d2 = _distances(walls, (sx, sy))
        dist = np.where((d2 >= 0) & (d2 < dist), d2, dist)
    cells = [(x, y) for y, x in zip(*np.nonzero(free)) if dist[y, x] > 6
             and not any(sx - 2 <= x <= sx + w + 1 and sy - 2 <= y <= sy + h + 1 for sx, sy, w, h in starts)]
    cells.sort(key=lambda c: (int(dist[c[1], c[0]]), c))
    n_victims = 4 + round(4 * difficulty)
    lo = int(len(cells) * 0.6 * difficulty)  # harder: only the farther part of the map
    pool = cells[lo:] or cells
    victims: list[tuple[int, int]] = []
    for c in rng.sample(pool, min(len(pool), n_victims * 4)):
        if all(abs(c[0] - v[0]) + abs(c[1] - v[1]) >= 6 for v in victims):
            victims.append(c)
        if len(victims) == n_victims:
            break
    rubble = []
    for _ in range(1 + round(4 * difficulty)):
        w, h = rng.randint(3, 6), rng.randint(2, 4)
        x, y = rng.randrange(1, width - w - 1), rng.randrange(1, height - h - 1)
        if not any(sx - 1 <= x + w and x <= sx + sw and sy - 1 <= y + h and y <= sy + sh for sx, sy, sw, sh in starts):
            rubble.append((x, y, w, h))
    return _toml(seed, difficulty, walls, starts, victims, rubble, robots, rng)


def _connect(walls: np.ndarray, starts: list[tuple[int, int]], rng: random.Random) -> None:
    """Open walls until every free cell is reachable from the first start cell (a region cut off
    gets a doorway through the wall cell that joins it to the reachable part)."""
    h, w = walls.shape
    for _ in range(w * h):
        seen = reachable(walls, starts[:1])
        cut = (~walls) & (~seen)
        if not cut.any():
            return
        options = [(x, y) for y in range(1, h - 1) for x in range(1, w - 1) if walls[y, x]
                   and ((seen[y, x - 1] and cut[y, x + 1]) or (cut[y, x - 1] and seen[y, x + 1])
                        or (seen[y - 1, x] and cut[y + 1, x]) or (cut[y - 1, x] and seen[y + 1, x]))]
        if not options:  # no single wall between them: fill the unreachable cells
            walls[cut] = True
            return
        x, y = rng.choice(options)
        walls[y, x] = False


def _toml(seed: int, difficulty: float, walls: np.ndarray, starts: list[tuple[int, int, int, int]],
          victims: list[tuple[int, int]], rubble: list[tuple[int, int, int, int]], robots: int,
          rng: random.Random) -> str:
    h, w = walls.shape
    rows = "\n".join("".join("#" if c else "." for c in row) for row in walls)
    out = [f"# Generated by robo-comp scenario generate --seed {seed} --difficulty {difficulty:g} --size {w}x{h}",
           f'name = "Generated #{seed} (difficulty {difficulty:.2f})"', "cell_size = 25", "duration = 300",
           f"seed = {seed}", "shared_discoveries = false", f'map = """\n{rows}\n"""', ""]
    for x, y, rw, rh in rubble:
        out += ["[[zones]]", 'kind = "rubble"', f"x = {x}", f"y = {y}", f"w = {rw}", f"h = {rh}",
                f"speed_factor = {0.6 - 0.3 * difficulty:.2f}", f"danger = {0.2 + 0.4 * difficulty:.2f}",
                "cost = 3", ""]
    for i, (x, y) in enumerate(victims, start=1):
        kind = rng.choice(KINDS)
        out += ["[[victims]]", f'id = "v{i}"', f"x = {x}", f"y = {y}", f'kind = "{kind}"', ""]
    for (name, colour), (x, y, sw, sh) in zip(_TEAMS, starts):
        out += ["[[teams]]", f'name = "{name}"', f'colour = "{colour}"',
                f"start = {{ x = {x}, y = {y}, w = {sw}, h = {sh} }}", f"robots = {robots}", ""]
    out += ["[positioning]", "rate = 2.0", "noise = 0.3", "dropout = 0.1", "",
            "[robot]", "speed = 2.0", "turn_rate = 90", 'drive = "grid4"', ""]
    return "\n".join(out)


def write_scenario(path: str | Path, seed: int, **kw: float | int) -> Path:
    """Write :func:`generate_scenario`'s text to ``path``; returns the path."""
    p = Path(path)
    p.write_text(generate_scenario(seed, **kw), encoding="utf-8")  # type: ignore[arg-type]
    return p


__all__ = ["generate_scenario", "reachable", "write_scenario"]

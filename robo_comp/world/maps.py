"""Grid maps: Moving AI ``.map``/``.scen`` files, our text grids and the thesis test maps.

Moving AI format (https://movingai.com/benchmarks/formats.html)::

    type octile
    height H
    width W
    map
    <H rows of W characters>

'.', 'G' and 'S' are passable; '@', 'O', 'T' and 'W' are blocked (trees and water are not
walkable for our robots). Our text grid (``.txt``/``.grid``) is rows of '.' (free) and '#'
(wall); lines starting with ';' are comments. Bad input raises
:class:`robo_comp.errors.ScenarioError` naming the file and line.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robo_comp.errors import ScenarioError

MOVINGAI_FREE = frozenset(".GS")
MOVINGAI_BLOCKED = frozenset("@OTW")
_FREE_CODES = np.frombuffer(b".GS", dtype=np.uint8)


@dataclass
class GridMap:
    """A grid of cells: ``walls[y, x]`` is True where the cell is blocked."""

    walls: np.ndarray
    name: str

    @property
    def width(self) -> int:
        """Number of columns (x range)."""
        return int(self.walls.shape[1])

    @property
    def height(self) -> int:
        """Number of rows (y range)."""
        return int(self.walls.shape[0])

    def passable(self, x: int, y: int) -> bool:
        """True when (x, y) lies inside the map and is not a wall."""
        return 0 <= x < self.width and 0 <= y < self.height and not bool(self.walls[y, x])


@dataclass
class ScenEntry:
    """One Moving AI scenario line: a query on ``map`` (of size w×h) and its optimal length."""

    bucket: int
    map: str
    w: int
    h: int
    sx: int
    sy: int
    gx: int
    gy: int
    optimal: float


def _read(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ScenarioError(f"{path}: no such file") from None
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"{path}: not a text file ({exc.reason})") from None
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read ({exc.strerror})") from None


def load_map(path: str | Path) -> GridMap:
    """Load a Moving AI ``.map`` file or a text grid (``.txt``/``.grid``/anything else).

    A file whose first non-blank line starts with ``type`` is read as Moving AI format.
    """
    p = Path(path)
    text = _read(p)
    first = next((ln.strip() for ln in text.splitlines() if ln.strip()), "")
    if p.suffix == ".map" or first.startswith("type "):
        return parse_movingai(text, source=str(p))
    return parse_text_grid(text, source=str(p))


def parse_movingai(text: str, source: str = "<string>") -> GridMap:
    """Parse the text of a Moving AI ``.map`` file."""
    lines = text.splitlines()
    header: dict[str, str] = {}
    i = 0
    while i < len(lines):
        raw = lines[i].strip()
        i += 1
        if not raw:
            continue
        if raw == "map":
            break
        key, _, value = raw.partition(" ")
        if key not in ("type", "height", "width"):
            raise ScenarioError(
                f"{source} line {i}: expected header 'type', 'height', 'width' or 'map', "
                f"got {raw[:40]!r}")
        header[key] = value.strip()
    else:
        raise ScenarioError(f"{source} line {i}: missing header line 'map'"
                            if lines else f"{source}: empty file")
    for key in ("type", "height", "width"):
        if key not in header:
            raise ScenarioError(f"{source}: missing header '{key}'")
    dims = {}
    for key in ("height", "width"):
        try:
            dims[key] = int(header[key])
        except ValueError:
            raise ScenarioError(f"{source}: header {key} {header[key]!r} is not an integer") from None
        if dims[key] <= 0:
            raise ScenarioError(f"{source}: header {key} must be positive, got {dims[key]}")
    h, w = dims["height"], dims["width"]
    rows = lines[i:i + h]
    if len(rows) < h:
        raise ScenarioError(f"{source} line {i + len(rows) + 1}: map has {len(rows)} rows, "
                            f"expected {h}")
    for extra in range(i + h, len(lines)):
        if lines[extra].strip():
            raise ScenarioError(f"{source} line {extra + 1}: extra row after the {h} map rows")
    walls = np.zeros((h, w), dtype=bool)
    for y, row in enumerate(rows):
        lineno = i + y + 1
        row = row.rstrip("\r")
        if len(row) != w:
            raise ScenarioError(f"{source} line {lineno}: row has {len(row)} cells, expected {w}")
        bad = set(row) - MOVINGAI_FREE - MOVINGAI_BLOCKED
        if bad:
            ch = sorted(bad)[0]
            raise ScenarioError(f"{source} line {lineno}: unknown cell character {ch!r} "
                                f"at column {row.index(ch) + 1}")
        walls[y] = ~np.isin(np.frombuffer(row.encode("ascii"), dtype=np.uint8), _FREE_CODES)
    return GridMap(walls=walls, name=Path(source).stem)


def parse_text_grid(text: str, source: str = "<string>") -> GridMap:
    """Parse our text grid: rows of '.' (free) and '#' (wall); ';' starts a comment line."""
    rows: list[tuple[int, str]] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.rstrip("\r").rstrip()
        if not line or line.lstrip().startswith(";"):
            continue
        rows.append((lineno, line))
    if not rows:
        raise ScenarioError(f"{source}: empty map (no grid rows)")
    w = len(rows[0][1])
    walls = np.zeros((len(rows), w), dtype=bool)
    for y, (lineno, line) in enumerate(rows):
        bad = set(line) - {".", "#"}
        if bad:
            ch = sorted(bad)[0]
            raise ScenarioError(f"{source} line {lineno}: unknown cell character {ch!r} at "
                                f"column {line.index(ch) + 1} (use '.' free, '#' wall)")
        if len(line) != w:
            raise ScenarioError(f"{source} line {lineno}: row has {len(line)} cells, expected {w}")
        walls[y] = np.frombuffer(line.encode("ascii"), dtype=np.uint8) == ord("#")
    name = Path(source).stem if source != "<string>" else "grid"
    return GridMap(walls=walls, name=name)


def load_scen(path: str | Path) -> list[ScenEntry]:
    """Load a Moving AI ``.scen`` file (``version 1`` header, tab-separated lines)."""
    p = Path(path)
    entries: list[ScenEntry] = []
    for lineno, raw in enumerate(_read(p).splitlines(), start=1):
        line = raw.strip()
        if not line or (lineno == 1 and line.startswith("version")):
            continue
        parts = line.split("\t") if "\t" in line else line.split()
        if len(parts) != 9:
            raise ScenarioError(f"{p} line {lineno}: expected 9 fields, got {len(parts)}")
        try:
            entries.append(ScenEntry(int(parts[0]), parts[1], int(parts[2]), int(parts[3]),
                                     int(parts[4]), int(parts[5]), int(parts[6]),
                                     int(parts[7]), float(parts[8])))
        except ValueError as exc:
            raise ScenarioError(f"{p} line {lineno}: bad field ({exc})") from None
    return entries


def thesis_map(kind: int, n: int) -> GridMap:
    """The n×n test maps of the thesis's figure 5.1 (start (0,0), goal (n-1,n-1)).

    1 open; 2 anti-diagonal wall (x + y = n - 1), no path; 3 that wall with (n-1, 0) open;
    4 with (0, n-1) open; 5 with the middle cell (n//2, n-1-n//2) open.
    """
    if kind not in (1, 2, 3, 4, 5):
        raise ValueError(f"thesis map kind must be 1..5, got {kind}")
    if n < 2:
        raise ValueError(f"thesis map size must be >= 2, got {n}")
    walls = np.zeros((n, n), dtype=bool)
    if kind >= 2:
        idx = np.arange(n)
        walls[n - 1 - idx, idx] = True  # walls[y, x] with x + y = n - 1
        opening = {3: (n - 1, 0), 4: (0, n - 1), 5: (n // 2, n - 1 - n // 2)}.get(kind)
        if opening is not None:
            walls[opening[1], opening[0]] = False
    return GridMap(walls=walls, name=f"thesis{kind}-{n}")

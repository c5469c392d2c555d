"""Map loaders: Moving AI .map/.scen, text grids, thesis maps, and their error messages."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robo_comp.errors import ScenarioError
from robo_comp.world.maps import GridMap, load_map, load_scen, parse_text_grid, thesis_map

MAI = "type octile\nheight 3\nwidth 4\nmap\n....\n.@T.\nGS..\n"


def write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_movingai_map(tmp_path):
    m = load_map(write(tmp_path, "a.map", MAI))
    assert (m.width, m.height, m.name) == (4, 3, "a")
    assert m.walls.dtype == bool
    assert m.walls[1, 1] and m.walls[1, 2]          # '@' and 'T' blocked
    assert not m.walls[2, 0] and not m.walls[2, 1]  # 'G' and 'S' passable
    assert m.passable(0, 0) and not m.passable(1, 1) and not m.passable(4, 0)


def test_text_grid_with_comments(tmp_path):
    m = load_map(write(tmp_path, "g.txt", "; a comment\n..#\n#..\n; end\n"))
    assert m.walls.tolist() == [[False, False, True], [True, False, False]]
    assert isinstance(parse_text_grid(".#\n"), GridMap)


@pytest.mark.parametrize("text, where", [
    ("type octile\nheight 3\nwidth 4\nmap\n....\n.@.\n....\n", "line 6: row has 3 cells, expected 4"),
    ("type octile\nheight 3\nwidth 4\nmap\n....\n.x..\n....\n", "line 6: unknown cell character 'x'"),
    ("height 3\nwidth 4\nmap\n....\n....\n....\n", "missing header 'type'"),
    ("type octile\nheight 3\nwidth 4\n....\n", "line 4: expected header"),
    ("type octile\nheight 3\nwidth 4\nmap\n....\n", "line 6: map has 1 rows, expected 3"),
    ("type octile\nheight x\nwidth 4\nmap\n", "height 'x' is not an integer"),
    ("type octile\nheight 1\nwidth 2\nmap\n..\n..\n", "line 6: extra row"),
    ("", "empty"),
])
def test_bad_movingai(tmp_path, text, where):
    p = write(tmp_path, "bad.map", text)
    with pytest.raises(ScenarioError) as ei:
        load_map(p)
    assert str(p) in str(ei.value) and where in str(ei.value)


@pytest.mark.parametrize("text, where", [
    ("...\n..\n", "line 2: row has 2 cells, expected 3"),
    ("; c\n..\n.x\n", "line 3: unknown cell character 'x'"),
    ("; only comments\n\n", "empty map"),
])
def test_bad_text_grid(tmp_path, text, where):
    p = write(tmp_path, "bad.grid", text)
    with pytest.raises(ScenarioError) as ei:
        load_map(p)
    assert str(p) in str(ei.value) and where in str(ei.value)


def test_missing_and_binary_files(tmp_path):
    with pytest.raises(ScenarioError, match="no such file"):
        load_map(tmp_path / "nope.map")
    p = tmp_path / "bin.map"
    p.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ScenarioError, match="not a text file"):
        load_map(p)


def test_scen(tmp_path):
    p = write(tmp_path, "a.map.scen",
              "version 1\n0\tmaps/a.map\t4\t3\t0\t0\t3\t2\t3.82842712\n")
    (e,) = load_scen(p)
    assert (e.bucket, e.map, e.w, e.h, e.sx, e.sy, e.gx, e.gy) == (0, "maps/a.map", 4, 3, 0, 0, 3, 2)
    assert e.optimal == pytest.approx(3.82842712)
    bad = write(tmp_path, "b.map.scen", "version 1\n0\tmaps/a.map\t4\t3\t0\n")
    with pytest.raises(ScenarioError, match="line 2: expected 9 fields"):
        load_scen(bad)


def test_thesis_maps():
    n = 10
    assert not thesis_map(1, n).walls.any()
    w2 = thesis_map(2, n).walls
    assert w2.sum() == n and all(w2[n - 1 - x, x] for x in range(n))
    assert thesis_map(3, n).passable(n - 1, 0)
    assert thesis_map(4, n).passable(0, n - 1)
    m5 = thesis_map(5, n)
    assert m5.passable(n // 2, n - 1 - n // 2) and m5.walls.sum() == n - 1
    with pytest.raises(ValueError):
        thesis_map(6, n)


def test_real_movingai_files_if_present():
    root = Path(__file__).resolve().parents[2] / "shared" / "maps" / "movingai" / "dao"
    if not (root / "arena.map").exists():
        pytest.skip("Moving AI maps not available")
    m = load_map(root / "arena.map")
    assert (m.width, m.height) == (49, 49)
    assert np.any(m.walls) and len(load_scen(root / "arena.map.scen")) > 0

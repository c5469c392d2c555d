"""``robo-comp plan`` run as a real subprocess (python -m robo_comp.world.plan_cli)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

GRID = "; test map\n.....\n.###.\n.#...\n.#.#.\n...#.\n"


def plan(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "robo_comp.world.plan_cli", *args],
                          capture_output=True, text=True, timeout=60)


@pytest.fixture()
def grid(tmp_path: Path) -> Path:
    p = tmp_path / "g.txt"
    p.write_text(GRID)
    return p


def test_text_and_json(grid):
    r = plan(str(grid), "0,0", "4,4")
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("cost 8,")
    assert r.stdout.splitlines()[1].split()[0] == "0,0"
    r = plan(str(grid), "0,0", "2,2", "--json", "--diagonal")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["path"][0] == [0, 0] and out["path"][-1] == [2, 2]
    assert out["cost"] > 0 and out["seconds"] >= 0


def test_no_path_is_not_an_error(tmp_path):
    p = tmp_path / "split.grid"
    p.write_text("..#..\n..#..\n")
    r = plan(str(p), "0,0", "4,1", "--json")
    assert r.returncode == 0
    assert json.loads(r.stdout)["path"] is None and json.loads(r.stdout)["cost"] is None
    assert "no path" in plan(str(p), "0,0", "4,1").stdout


@pytest.mark.parametrize("args, msg", [
    (["missing.map", "0,0", "1,1"], "no such file"),
    (["{g}", "0;0", "1,1"], "START must be x,y"),
    (["{g}", "1,1", "0,0"], "START 1,1 is a wall"),
    (["{g}", "0,0", "9,0"], "GOAL 9,0 is outside the 5x5 map"),
    (["{g}", "0,0"], "START and GOAL are required"),
])
def test_errors_one_line_exit_2(grid, args, msg):
    r = plan(*[a.format(g=grid) for a in args])
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and msg in lines[0] and "Traceback" not in r.stderr


def test_bad_map_names_line(tmp_path):
    p = tmp_path / "bad.map"
    p.write_text("type octile\nheight 2\nwidth 3\nmap\n...\n.?.\n")
    r = plan(str(p), "0,0", "1,1")
    assert r.returncode == 2 and "line 6" in r.stderr and "Traceback" not in r.stderr


def test_scen(tmp_path):
    m = tmp_path / "a.map"
    m.write_text("type octile\nheight 3\nwidth 4\nmap\n....\n.@..\n....\n")
    s = tmp_path / "a.map.scen"
    s.write_text("version 1\n"
                 "0\ta.map\t4\t3\t0\t0\t3\t2\t4.41421356\n"
                 "0\ta.map\t4\t3\t0\t0\t3\t0\t3\n"
                 "0\ta.map\t4\t3\t0\t0\t0\t2\t9\n")
    r = plan(str(m), "--scen", str(s))
    assert r.returncode == 0, r.stderr
    assert "3 queries, 1 mismatches" in r.stdout and "line 4" in r.stdout
    r = plan(str(m), "--scen", str(s), "--limit", "2", "--json")
    out = json.loads(r.stdout)
    assert out["queries"] == 2 and out["mismatches"] == []

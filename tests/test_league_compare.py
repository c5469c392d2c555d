"""A/B comparison and crash forensics, through the commands a student runs.

``league compare`` plays two real variants of the team template's league entry (the template
as shipped, and the same code with every robot giving up after its first waypoint) against a
reference team on the same seeds and must say B is worse, with an interval below 0 and the
replay commands. A league with an entrant that crashes names the robot, the call, the line and
the traceback in ``league table --json``, the HTML report and ``league rerun``, whose log is
the match's own, byte for byte.
"""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

from robo_comp.league.compare import paired_interval, t975

ROOT = Path(__file__).resolve().parent.parent
TEMPLATE_PLAY = ROOT / "robo_comp" / "teams" / "template" / "extensions" / "play.py"

#: An entrant whose play fails on its line 9, inside a helper, after a robot call.
CRASHER = '''MANIFEST = {"name": "crasher", "version": "1.0", "kind": "extension", "description": "fails",
    "tasks": {"play": {"description": "turn, then fail", "args": [{"name": "width", "type": "int"},
        {"name": "height", "type": "int"}, {"name": "index", "type": "int"}, {"name": "count", "type": "int"}]}}}


def pick(cells, k):
    seen = robot_cells = cells
    return robot_cells[k]


def play(robot, width, height, index, count):
    robot.turn(90)
    here = robot.position()
    return pick([here], 3)
'''


def robo(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "robo_comp.cli", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


def test_the_interval_is_students_t_on_the_paired_differences():
    assert abs(t975(4) - 2.776) < 1e-9 and abs(t975(120) - 1.980) < 0.001
    mean, low, high = paired_interval([1.0, 2.0, 3.0, 4.0, 5.0])
    assert mean == 3.0 and abs((high - mean) - 2.776 * (10 / 4) ** 0.5 / 5 ** 0.5) < 1e-9 and low < mean


def test_compare_says_a_version_that_gives_up_early_is_worse(tmp_path):
    a = tmp_path / "a"
    b = tmp_path / "b"
    (a / "extensions").mkdir(parents=True)
    (b / "extensions").mkdir(parents=True)
    source = TEMPLATE_PLAY.read_text()
    (a / "extensions" / "play.py").write_text(source)
    # B: the same code, but each robot stops after its first waypoint (5 seeds: with 3 the interval
    # of -35, -35, -15 still held 0)
    weaker = source.replace("    return len(mine)", "        if k >= 0:\n            return 0\n    return len(mine)")
    assert weaker != source
    (b / "extensions" / "play.py").write_text(weaker)
    out = robo("league", "compare", str(a), str(b), "--against", "sitter", "--scenarios", "demo_room",
               "--seeds", "5", "--robots", "2", "--seconds", "45", "--workers", "2", "--out", str(tmp_path / "logs"),
               cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    text = out.stdout
    m = re.search(r"B - A: ([+-][\d.]+) points a match, 95 % confidence interval \[([+-][\d.]+|-inf), ([+-][\d.]+)\]", text)
    assert m, text
    assert float(m.group(1)) < 0 and float(m.group(3)) < 0, text
    assert "B is worse than A" in text and "5 pairs of matches" in text, text
    replays = re.findall(r"^ +robo-comp web --replay (\S+)$", text, re.M)
    assert len(replays) == 6 and all(Path(p).is_file() for p in replays), text


def test_a_crash_names_robot_call_line_and_traceback_and_reruns_the_same_match(tmp_path):
    league = tmp_path / "lg"
    (tmp_path / "crasher.py").write_text(CRASHER)
    assert robo("league", "init", str(league), "--reference", "1", "--scenarios", "demo_room", "--robots", "1",
                "--seconds", "10", cwd=tmp_path).returncode == 0
    assert robo("league", "submit", str(league), "crasher", "crasher.py", cwd=tmp_path).returncode == 0
    run = robo("league", "run", str(league), "--format", "round-robin", "--workers", "1", cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-3000:]
    view = json.loads(robo("league", "table", str(league), "--json", cwd=tmp_path).stdout)
    match = view["matches"][0]
    crash = match["crashes"][0]
    assert crash["team"] == "crasher" and crash["tag"] == 101 and crash["task"] == "play"
    assert crash["line"] == 8 and "IndexError" in crash["message"], crash
    assert crash["call"] == "robot.position()" and crash["t"] > 0, crash
    assert crash["traceback"] == ["crasher.py:14 in play: return pick([here], 3)",
                                  "crasher.py:8 in pick: return robot_cells[k]"], crash
    assert any(n == f"reproduce it: robo-comp league rerun {league} {match['id']}" for n in match["notes"]), match
    report = tmp_path / "report.html"
    assert robo("league", "report", str(league), str(report), cwd=tmp_path).returncode == 0
    page = report.read_text()
    assert "Where team code crashed" in page and "crasher.py:8 in pick: return robot_cells[k]" in page
    assert f"seed {match['seed']}" in page
    again = robo("league", "rerun", str(league), str(match["id"]), "--log", "again.log", cwd=tmp_path)
    assert again.returncode == 0, again.stderr[-3000:]
    assert "line 8" in again.stdout and "its last robot call: robot.position()" in again.stdout, again.stdout
    assert (tmp_path / "again.log").read_bytes() == (league / match["log"]).read_bytes()

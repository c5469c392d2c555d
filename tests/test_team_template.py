"""The newcomer's path: ``new-team``, the team template's own tests, the explorer in the sandbox,
and the ``robo_comp.testing`` pytest plugin (bench and real match)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from robo_comp.errors import BadTaskError, FieldError, UploadError
from robo_comp.sandbox.parent import Sandbox, TaskDone, TaskFailed
from robo_comp.teams import newteam
from robo_comp.testing import Bench, TaskError, start_match, wait_robots

ROOT = Path(__file__).parent.parent
TEMPLATE = ROOT / "robo_comp" / "teams" / "template"
VISIBLE = ROOT / "team_templates"
EXPLORER = (TEMPLATE / "extensions" / "explorer.py").read_text()


def tree(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` except caches, as ``{relative path: bytes}``."""
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file() and not {"__pycache__", ".pytest_cache"} & set(p.relative_to(root).parts)}


def run_pytest(folder: Path, *args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    """``python -m pytest`` inside ``folder`` in a fresh process (no PYTHONPATH from this run)."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTEST_ADDOPTS")}
    env["SDL_VIDEODRIVER"] = "dummy"
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *args],
                          cwd=folder, env=env, capture_output=True, text=True, timeout=timeout)


# ------------------------------------------------------------------ the template and new-team
def test_visible_template_is_the_shipped_one():
    # team_templates/ is a link to the package data: one tree, nothing to keep in step
    assert VISIBLE.is_symlink() and VISIBLE.resolve() == TEMPLATE.resolve()
    shipped = tree(TEMPLATE)
    assert {"README.md", "pyproject.toml", "extensions/explorer.py"} <= set(shipped)
    assert newteam.template_files() == shipped  # what new-team copies is exactly that tree


def test_new_team_copies_the_template_and_names_the_package(tmp_path):
    rc = newteam.main(["red_rovers", "--dest", str(tmp_path)])
    assert rc == 0
    team = tmp_path / "red_rovers"
    copied, shipped = tree(team), tree(TEMPLATE)
    assert sorted(copied) == sorted(shipped)
    assert 'name = "red_rovers"' in copied["pyproject.toml"].decode()
    assert 'name = "my-team"' not in copied["pyproject.toml"].decode()
    assert all(copied[n] == shipped[n] for n in shipped if n != "pyproject.toml")


def test_new_team_refuses_bad_names_and_existing_folders(tmp_path, capsys):
    with pytest.raises(FieldError, match="team name"):
        newteam.create_team("../evil", tmp_path)
    (tmp_path / "taken").mkdir()
    (tmp_path / "taken" / "keep.txt").write_text("mine")
    assert newteam.main(["taken", "--dest", str(tmp_path)]) == 2
    assert "already exists" in capsys.readouterr().err
    assert (tmp_path / "taken" / "keep.txt").read_text() == "mine"


def test_new_team_command_line(tmp_path):
    """The subcommand through argparse as ``robo-comp`` will wire it (``add_parser(sub)``)."""
    import argparse

    parser = argparse.ArgumentParser(prog="robo-comp")
    newteam.add_parser(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["new-team", "blue_team", "--dest", str(tmp_path)])
    assert args.func(args) == 0
    assert (tmp_path / "blue_team" / "extensions" / "explorer.py").read_text() == EXPLORER


def test_copied_template_fast_tests_pass(tmp_path):
    team = newteam.create_team("rescuers", tmp_path)
    res = run_pytest(team, "-m", "not slow")
    assert res.returncode == 0, res.stdout[-4000:] + res.stderr[-2000:]
    assert " passed" in res.stdout and " deselected" in res.stdout  # the real-match tests are marked slow


def test_copied_template_tests_fail_when_the_explorer_is_broken(tmp_path):
    """The template's tests can fail: break the explorer and they must say so."""
    team = newteam.create_team("breakers", tmp_path)
    src = team / "extensions" / "explorer.py"
    src.write_text(src.read_text().replace("taken.append(robot.take_picture())", "robot.take_picture()"))
    res = run_pytest(team, "-m", "not slow", "tests/test_extensions.py")
    assert res.returncode == 1, res.stdout[-3000:]
    assert "FAILED tests/test_extensions.py::test_explore_then_report_scores_a_victim" in res.stdout
    assert "FAILED tests/test_extensions.py::test_a_wrong_report_costs_points" in res.stdout
    assert "2 failed" in res.stdout


@pytest.mark.slow
def test_copied_template_all_tests_pass_including_the_real_match(tmp_path):
    team = newteam.create_team("full", tmp_path)
    res = run_pytest(team, timeout=180)
    assert res.returncode == 0, res.stdout[-4000:] + res.stderr[-2000:]
    assert " passed" in res.stdout and "failed" not in res.stdout


# ------------------------------------------------------------------ the explorer in the real Sandbox
class Recorder:
    """A robot handler answering like a tiny world: a picture id per picture, a path, a pose."""

    def __init__(self) -> None:
        self.calls: list[tuple[int, str, list]] = []

    def __call__(self, tag: int, name: str, args: list):
        self.calls.append((tag, name, args))
        if name == "plan":
            if args == [0, 0]:  # as the host refuses a wall: RobotError in team code
                raise BadTaskError("(0, 0) is a wall or outside the arena")
            return [[1, 1], [int(args[0]), int(args[1])]]
        if name == "take_picture":
            return sum(1 for c in self.calls if c[1] == "take_picture")
        if name == "sense":
            return {"front": 50.0, "left": None, "right": 80.0, "down": 20.0}
        if name == "report_find":
            return {"id": 1, "state": "confirmed", "message": f"evidence {args[3]}"}
        return [float(args[0]) if args else 1.0, 1.0, 0.0]


def test_explorer_loads_and_runs_through_the_real_sandbox():
    host = Recorder()
    with Sandbox("red", [7], host, seed=1) as sb:
        info = sb.load("explorer.py", EXPLORER)
        assert (info.name, info.kind) == ("explorer", "extension")
        adv = sb.advertised_tasks()
        assert [a["type"] for a in adv["explore"]["args"]] == ["points"]
        assert [a["name"] for a in adv["report_victim"]["args"]] == ["x", "y", "kind"]
        assert not adv["explore"]["replaces_builtin"]
        done = sb.run_task(7, "explore", [[[4, 5], [0, 0]]], timeout=10)
        assert isinstance(done, TaskDone), done
        assert done.result == {"visited": [[4, 5]], "skipped": [[0, 0]], "pictures": [1, 2, 3, 4]}
        names = [c[1] for c in host.calls]
        assert names == ["plan", "go_to", "sense"] + ["take_picture", "turn"] * 4 + ["plan"]
        rep = sb.run_task(7, "report_victim", [4, 4, "child"], timeout=10)
        assert isinstance(rep, TaskDone) and rep.result["message"] == "evidence [1, 2, 3, 4]"
        assert host.calls[-1] == (7, "report_find", [4, 4, "child", [1, 2, 3, 4]])


def test_explorer_report_without_pictures_fails_with_its_line():
    with Sandbox("red", [7], Recorder()) as sb:
        sb.load("explorer.py", EXPLORER)
        rec = sb.run_task(7, "report_victim", [1, 1, "adult"], timeout=10)
        assert isinstance(rec, TaskFailed) and rec.reason == "error"
        assert "no pictures yet" in rec.message and rec.line is not None


# ------------------------------------------------------------------ the plugin: bench
def test_bench_is_deterministic_and_scores_with_the_real_rules():
    def play(seed: int) -> tuple:
        with Bench("demo_room", "red", seed=seed) as b:
            b.load(TEMPLATE / "extensions" / "explorer.py")
            out = b.run("explore", [[9, 6], [14, 9]])
            verdict = b.run("report_victim", 9, 5, "adult")
            return out, verdict, b.score(), b.log_text(), b.arena.time
    first, again, other = play(0), play(0), play(5)
    assert first == again
    assert first[0]["visited"] == [[9, 6], [14, 9]] and len(first[0]["pictures"]) == 8
    assert first[1]["state"] == "confirmed" and first[2] == 15
    assert "front " in first[3]
    # sensor noise and positioning come from the seed: another seed reads other ranges
    assert other[3] != first[3]


def test_bench_radios_through_the_match_and_refuses_bad_uploads():
    with Bench("demo_room", "blue", robots=2) as b:
        assert b.tags == [101, 102]
        assert b.true_cell(101)[0] >= 20  # blue starts on the right
        with pytest.raises(UploadError):
            b.load("x.py", "MANIFEST = {'name': 'x'}\n")
        b.load("r.py", 'MANIFEST = {"name": "r", "version": "1", "kind": "extension", '
                       '"tasks": {"call": {"args": [{"name": "to", "type": "int"}]}}}\n\ndef call(robot, to):\n    return robot.radio(to, "hi")\n')
        assert b.run("call", 101, tag=102) == 1  # the match delivered it to the teammate, as live
        assert b.by_tag[101].inbox[-1] == {"from": 102, "data": "hi"}
        with pytest.raises(TaskError, match="radio reaches your own team only"):
            b.run("call", 999, tag=102)
    with pytest.raises(FieldError, match="no team 'green'"):
        Bench("demo_room", "green")


# ------------------------------------------------------------------ the plugin: a real match
def test_start_match_runs_a_real_core_and_hosts(tmp_path):
    with start_match(tmp_path / "state", "demo_room") as m:
        assert m.teams == ["blue", "red"]
        m.robots("red", 2)
        red = m.client("red")
        rows = wait_robots(red, 2)
        assert {r["team"] for r in rows} == {"red"}
        assert m.proc.poll() is None and all(p.poll() is None for p in m.procs)
        assert m.scores()["phase"] == "running"  # practice mode
        assert m.score_of("red") == 0
        r = red.request("find", tag=rows[0]["tag"], x=2, y=2, kind="adult")
        assert r["state"] == "rejected"
        assert m.score_of("red") == -5
        assert any(e["data"]["state"] == "rejected" for e in m.logged_events("find.reported"))
    assert m.proc.poll() is not None and all(p.poll() is not None for p in m.procs)


def test_plugin_fixtures_are_registered(robo_scenario, robo_team):
    assert robo_scenario.name == "demo_room.toml" and robo_team == "red"

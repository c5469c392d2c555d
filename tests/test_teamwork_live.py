"""Issue 33 live: a real core process, real robot-host processes, the real ``robo-comp ctl``. A
host killed (SIGKILL) in the middle of a task: its robot's work reaches a teammate on another
host; debris a robot finds reaches its team's map and nobody else's. The engine's half is in
test_teamwork.py (the same match model and task runtime)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from robo_comp.errors import ForbiddenError, NotYoursError
from robo_comp.testing import start_match, wait_for, wait_robots
from robo_comp.world.video import WEBM_MAGIC

TWO_WAYS = """
name = "two ways"
seed = 3
duration = 600
map = '''
################
#..............#
#..............#
####.########.##
#..............#
#..............#
################
'''
[[debris]]
x = 4
y = 3
[[teams]]
name = "red"
start = { x = 1, y = 1, w = 3, h = 2 }
robots = 3
[[teams]]
name = "blue"
start = { x = 14, y = 5, w = 1, h = 1 }
robots = 1
"""


def ctl(state: Path, token: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "robo_comp.cli", "ctl", "--core", str(state), "--token-file",
                           token, *args], capture_output=True, text=True, timeout=30)


def test_a_robot_whose_host_is_killed_mid_task_has_its_work_done_by_a_teammate(tmp_path):
    with start_match(tmp_path / "state", "office") as m:
        out = ctl(m.state, str(m.token_file("red")), "teamwork", "on")
        assert out.returncode == 0 and "reallocation of a lost robot's tasks is on" in out.stdout, out.stderr
        doomed = m.robots("red", 1, "--prefix", "doomed", speed=3.0)
        red = m.client("red", timeout=10)
        wait_robots(red, 1)
        m.robots("red", 1, "--prefix", "mate", speed=3.0)
        rows = {r["robot_id"]: r for r in wait_robots(red, 2)}
        lost, mate = rows["doomed-1"]["tag"], rows["mate-1"]["tag"]
        first = red.give(lost, "goTo", [40, 30])["task_id"]
        second = red.give(lost, "goTo", [10, 23], queue=True)["task_id"]
        wait_for(lambda: any(e["data"]["task_id"] == first for e in m.logged_events("task.started")), 10,
                 "the first goTo to start")
        wait_for(lambda: red.monitor(lost)["moving"], 10, "the robot to drive")
        doomed.kill()  # SIGKILL: no leave, no bye; the core hears nothing more from it
        doomed.wait()
        moved = wait_for(lambda: {e["data"]["from"]["task_id"]: e["data"] for e in m.logged_events("task.given")
                                  if e["data"].get("from")} or None, 20, "the tasks to move")
        assert set(moved) == {first, second} and {d["tag"] for d in moved.values()} == {mate}
        topics = [(e["topic"], e["data"].get("tag"), e["data"].get("task_id")) for e in m.logged_events()]
        lost_at = topics.index(("robot.lost", lost, None))
        offered_at = next(i for i, t in enumerate(topics) if t[0] == "task.offered")
        assert lost_at < offered_at  # offered when the loss was declared
        done = {e["data"]["task_id"]: e["data"] for e in m.logged_events("task.done")}
        for tid in (first, second):
            assert done[tid]["state"] == "cancelled" and f"moved to robot {mate}" in done[tid]["status"]

        def finished() -> dict | None:
            ends = {e["data"]["task_id"]: e["data"] for e in m.logged_events("task.done")}
            new = [ends.get(moved[t]["task_id"]) for t in (first, second)]
            return new if all(new) else None
        ends = wait_for(finished, 120, "the teammate to finish both tasks")
        assert all(d["ok"] and d["tag"] == mate for d in ends), ends
        assert ends[1]["result"]["reached"] == [10, 23]
        assert not [e for e in m.logged_events("robot.bump") if e["data"].get("with") == lost]


def test_debris_and_videos_reach_their_team_and_only_their_team(tmp_path):
    scenario = tmp_path / "two_ways.toml"
    scenario.write_text(TWO_WAYS)
    with start_match(tmp_path / "state", scenario) as m:
        m.robots("red", 1)  # the organiser's host: its arena has the debris (--scenario)
        red = m.client("red", timeout=10)
        tag = wait_robots(red, 1)[0]["tag"]
        blue = m.client("blue", timeout=10)
        assert red.request("map")["obstacles"] == []
        tid = red.give(tag, "goTo", [4, 5])["task_id"]
        d = wait_for(lambda: next((e["data"] for e in m.logged_events("task.done") if e["data"]["task_id"] == tid),
                                  None), 60, "the goTo to end")
        assert d["ok"], d  # through the other door
        assert [(e["data"]["tag"], e["data"]["x"], e["data"]["y"]) for e in m.logged_events("map.obstacle")] == [
            (tag, 4, 3)]
        assert red.request("map")["obstacles"] == [[4, 3]]
        assert blue.request("map")["obstacles"] == []  # blue's robots must find it themselves
        assert m.referee().request("map")["obstacles"] == [[4, 3]]
        assert not m.logged_events("robot.bump")
        # a team's token speaks for no robot: only the organiser's host reports what the world holds
        with pytest.raises(ForbiddenError):
            red.request("obstacle", tag=tag, x=5, y=5)
        # examineArea films; the film is the team's and the referee's
        tid = red.give(tag, "examineArea", [4, 5])["task_id"]
        d = wait_for(lambda: next((e["data"] for e in m.logged_events("task.done") if e["data"]["task_id"] == tid),
                                  None), 60, "examineArea to end")
        assert d["ok"] and d["result"]["videos"] == [1], d
        film = red.request("video.get", id=1)
        assert film["webm"].startswith(WEBM_MAGIC) and film["frames"] >= 30 and film["tag"] == tag
        with pytest.raises(NotYoursError):
            blue.request("video.get", id=1)
        assert (m.state / "videos" / "1.webm").stat().st_mode & 0o777 == 0o600

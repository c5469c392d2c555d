"""Ownership: a team sees and commands only its own robots; the referee sees all."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from conftest import wait_robots
from robo_comp.client import Client
from robo_comp.errors import AuthError, NotYoursError, NoSuchRobotError


def test_teams_see_only_their_robots_and_cross_team_commands_are_refused(core):
    core.robots("red", 2)
    core.robots("blue", 2)
    red, blue, ref = core.client("red"), core.client("blue"), core.client("referee")
    reds = wait_robots(red, 2)
    blues = wait_robots(blue, 2)
    assert {r["team"] for r in reds} == {"red"} and len(red.robots()) == 2
    assert {r["team"] for r in blues} == {"blue"}
    assert len(wait_robots(ref, 4)) == 4
    btag = blues[0]["tag"]
    for call in (lambda: red.monitor(btag), lambda: red.tasks(btag), lambda: red.stop(btag),
                 lambda: red.give(btag, "goTo", [1, 1]), lambda: red.give(btag, "goTo", [1, 1], queue=True)):
        with pytest.raises(NotYoursError) as e:
            call()
        assert e.value.code == "E_NOT_YOURS"
        assert "only see and command its own robots" in e.value.message
        assert "blue" not in e.value.message  # nothing is revealed about the owner
    # the referee may command anyone; unknown tags are reported as such to the referee
    assert ref.give(btag, "goTo", [2, 2])["task_id"] > 0
    with pytest.raises(NoSuchRobotError):
        ref.monitor(9999)
    # a team asking for an unknown tag learns nothing more than for another team's robot
    with pytest.raises(NotYoursError):
        red.monitor(9999)


def test_refusals_are_logged_and_shown_to_the_team(core):
    core.robots("blue", 1)
    blue = core.client("blue")
    btag = wait_robots(blue, 1)[0]["tag"]
    red = core.client("red")
    red.watch(True)
    with pytest.raises(NotYoursError):
        red.stop(btag)
    ev = red.next_event(2.0)
    while ev is not None and ev["topic"] != "refused":
        ev = red.next_event(2.0)
    assert ev is not None and ev["data"]["code"] == "E_NOT_YOURS" and ev["data"]["type"] == "stop"


def test_bad_token_and_no_hello_are_refused(core):
    with pytest.raises(AuthError) as e:
        Client(str(core.state), "not-a-token", timeout=3)
    assert "token" in e.value.message


def test_token_files_are_private(core):
    for p in [core.state / "referee.token", *(core.state / "teams").iterdir()]:
        assert p.stat().st_mode & 0o777 == 0o600
    info = json.loads((core.state / "core.json").read_text())
    assert info["router"].startswith("tcp://127.0.0.1:") and info["teams"] == ["red", "blue"]


def ctl(core, team, *args):
    tok = core.state / ("referee.token" if team == "referee" else f"teams/{team}.token")
    return subprocess.run([sys.executable, "-m", "robo_comp.cli", "ctl", "--core", str(core.state),
                           "--token-file", str(tok), *args], capture_output=True, text=True, timeout=30)


def test_ctl_lists_gives_and_is_refused_with_exit_1(core):
    core.robots("red", 1)
    core.robots("blue", 1)
    red = core.client("red")
    rtag = wait_robots(red, 1)[0]["tag"]
    btag = wait_robots(core.client("blue"), 1)[0]["tag"]
    out = ctl(core, "red", "--json", "robots")
    assert out.returncode == 0, out.stderr
    rows = json.loads(out.stdout)
    assert [r["tag"] for r in rows] == [rtag]
    out = ctl(core, "red", "give", str(rtag), "goTo", "[3, 4]")
    assert out.returncode == 0 and "given to robot" in out.stdout
    out = ctl(core, "red", "tasks", str(rtag))
    assert out.returncode == 0 and "goTo(x: int, y: int)" in out.stdout
    out = ctl(core, "red", "give", str(btag), "goTo", "[3, 4]")
    assert out.returncode == 1 and "E_NOT_YOURS" in out.stderr and "Traceback" not in out.stderr
    out = ctl(core, "red", "give", str(rtag), "goTo", "[3, oops")
    assert out.returncode == 2 and "JSON list" in out.stderr
    out = ctl(core, "red", "give", str(rtag), "fly", "[]")
    assert out.returncode == 1 and "E_BAD_TASK" in out.stderr and "goTo" in out.stderr
    out = ctl(core, "red", "monitor", str(rtag))
    assert out.returncode == 0 and "can run" in out.stdout
    out = ctl(core, "red", "stop", str(rtag))
    assert out.returncode == 0 and "halted" in out.stdout
    bad = subprocess.run([sys.executable, "-m", "robo_comp.cli", "ctl", "--core", str(core.state),
                          "--token", "wrong", "robots"], capture_output=True, text=True, timeout=30)
    assert bad.returncode == 1 and "E_AUTH" in bad.stderr

"""A real match on this machine: a core process and a robot-host process, as on match day.

``robo_match`` starts the core for the scenario in pyproject.toml (practice mode: the match runs
at once). The first test uploads our explorer and lets it find and report a victim; the second
does the same by hand with the built-in ``examineArea`` task and a ``find`` from the console side.
"""
from pathlib import Path

import pytest

from robo_comp.testing import next_event_where, wait_robots

EXPLORER = Path(__file__).parent.parent / "extensions" / "explorer.py"


def finished(client, task_id, timeout=60):
    """The ``task.done`` event of ``task_id`` (the client must be watching)."""
    return next_event_where(client, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == task_id,
                            timeout=timeout)["data"]


@pytest.mark.slow
def test_upload_the_explorer_and_score_in_a_real_match(robo_match, robo_team):
    if robo_match.scenario is None or robo_match.scenario.stem != "demo_room":
        pytest.skip("written for the bundled demo_room scenario")
    robo_match.robots(robo_team, 1, speed=6)
    me = robo_match.client(robo_team, timeout=30)  # the first upload starts the robot's sandbox
    me.watch(True)
    tag = wait_robots(me, 1)[0]["tag"]
    reply = me.upload([tag], EXPLORER.name, EXPLORER.read_text())
    assert reply["ok"], reply
    done = finished(me, me.give(tag, "explore", [[[9, 6]]])["task_id"])
    assert done["ok"], done
    assert len(done["result"]["pictures"]) == 4
    done = finished(me, me.give(tag, "report_victim", [9, 5, "adult"])["task_id"])
    assert done["ok"] and done["result"]["state"] == "confirmed", done
    assert robo_match.score_of(robo_team) == 15


@pytest.mark.slow
def test_examine_and_report_scores_in_a_real_match(robo_match, robo_team):
    if robo_match.scenario is None or robo_match.scenario.stem != "demo_room":
        pytest.skip("written for the bundled demo_room scenario")
    robo_match.robots(robo_team, 1, speed=6)
    me = robo_match.client(robo_team)
    me.watch(True)
    tag = wait_robots(me, 1)[0]["tag"]
    done = finished(me, me.give(tag, "examineArea", [9, 6])["task_id"])
    assert done["ok"], done
    pictures = done["result"]["pictures"]
    answer = me.request("find", tag=tag, x=9, y=5, kind="adult", evidence=pictures)
    assert answer["state"] == "confirmed", answer
    assert robo_match.score_of(robo_team) == 15

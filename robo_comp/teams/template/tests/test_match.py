"""A real match on this machine: a core process and a robot-host process, as on match day.

``robo_match`` starts the core for the scenario in pyproject.toml (practice mode: the match runs
at once). The robot host does not run uploaded modules yet, so this test drives the built-in
``examineArea`` task and reports the find from the console side, the way a team does by hand.
"""
import pytest

from robo_comp.testing import next_event_where, wait_robots


@pytest.mark.slow
def test_examine_and_report_scores_in_a_real_match(robo_match, robo_team):
    if robo_match.scenario is None or robo_match.scenario.stem != "demo_room":
        pytest.skip("written for the bundled demo_room scenario")
    robo_match.robots(robo_team, 1, speed=6)
    me = robo_match.client(robo_team)
    me.watch(True)
    tag = wait_robots(me, 1)[0]["tag"]
    task_id = me.give(tag, "examineArea", [9, 6])["task_id"]
    done = next_event_where(me, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == task_id,
                            timeout=60)["data"]
    assert done["ok"], done
    pictures = done["result"]["pictures"]
    answer = me.request("find", tag=tag, x=9, y=5, kind="adult", evidence=pictures)
    assert answer["state"] == "confirmed", answer
    assert robo_match.score_of(robo_team) == 15

"""Fast tests of the consoles' parts that need no core: argument parsing, the model, the link."""
from __future__ import annotations

import asyncio

import pytest

from robo_comp.errors import ConnectionLostError, NotYoursError
from robo_comp.link import CoreLink, LinkState
from robo_comp.tui.model import ConsoleModel, LogEntry, describe_event, fmt_clock, task_label
from robo_comp.tui.testing import demo_data
from robo_comp.tui.widgets.task_form import parse_arg

INT = {"name": "x", "type": "int"}
PT = {"name": "p", "type": "point"}
PTS = {"name": "points", "type": "points"}


@pytest.mark.parametrize(("spec", "text", "value"), [
    (INT, " 12 ", 12), (INT, "-3", -3), ({"name": "f", "type": "float"}, "2.5", 2.5),
    ({"name": "f", "type": "float"}, "3", 3), ({"name": "s", "type": "str"}, "hello world", "hello world"),
    ({"name": "b", "type": "bool"}, "yes", True), ({"name": "b", "type": "bool"}, "false", False),
    (PT, "3, 4", [3, 4]), (PT, "(3 4)", [3, 4]), (PT, "[1.5, 2]", [1.5, 2]),
    (PTS, "1,1; 5,1; 5,6", [[1, 1], [5, 1], [5, 6]]), (PTS, "[[1, 2], [3, 4]]", [[1, 2], [3, 4]]),
])
def test_parse_arg_accepts(spec: dict, text: str, value: object) -> None:
    assert parse_arg(spec, text) == value


@pytest.mark.parametrize(("spec", "text", "words"), [
    (INT, "", "required"), (INT, "2.5", "whole number"), (INT, "abc", "whole number"),
    (PT, "3", "two numbers"), (PTS, "1,1; 2", "point 2"), (PTS, "[[1, 2], [3]]", "[x, y]"),
    ({"name": "b", "type": "bool"}, "maybe", "true or false"),
])
def test_parse_arg_explains_refusals(spec: dict, text: str, words: str) -> None:
    with pytest.raises(ValueError, match=words.replace("[", r"\[").replace("]", r"\]")):
        parse_arg(spec, text)


def test_model_follows_events() -> None:
    m = ConsoleModel(role="team", team="red", clock=lambda: 10.0, wall_clock=lambda: 0.0)
    m.load_snapshot(demo_data()["snapshot"])
    assert sorted(m.robots) == [101, 102, 103] and m.walls is not None and m.walls.shape == (20, 24)
    assert m.my_score()["rank"] == 1
    m.apply("task.given", "red", {"tag": 102, "task_id": 20, "name": "goTo", "args": [1, 1], "mode": "queue"})
    m.apply("task.given", "red", {"tag": 102, "task_id": 21, "name": "goTo", "args": [2, 2], "mode": "queue"})
    assert m.robots[102]["queue"] == 2
    m.apply("task.started", "red", {"tag": 102, "task_id": 20, "name": "goTo", "args": [1, 1]})
    assert m.robots[102]["queue"] == 1 and task_label(m.robots[102]["task"]) == "goTo(1, 1) #20"
    m.apply("task.done", "red", {"tag": 102, "task_id": 20, "name": "goTo", "ok": True, "state": "done",
                                 "status": "reached"})
    assert m.robots[102]["task"] is None
    assert m.apply("robot.positions", "red", {"team": "red", "tags": [102, 999], "x": [4.0, 1.0], "y": [5.0, 1.0],
                                              "heading": [90.0, 0.0], "moving": [True, True]}) is None  # not logged
    assert (m.robots[102]["x"], m.robots[102]["y"], m.robots[102]["moving"]) == (4.0, 5.0, True)
    assert 999 not in m.robots  # a pose for a robot the console does not know adds nothing
    m.apply("robot.lost", "red", {"tag": 102, "message": "silent"})
    assert m.robots[102]["status"] == "lost"
    m.apply("robot.stopped", "red", {"tag": 101, "cancelled": [7, 8], "ms": 2.0})
    assert m.robots[101]["queue"] == 0 and m.robots[101]["task"] is None
    m.apply("match.phase", "*", {"phase": "running", "elapsed": 5.0, "remaining": 100.0})
    assert m.match.now(12.0) == (7.0, 98.0)
    assert [e.topic for e in m.recent(102)][-2:] == ["task.done", "robot.lost"]


def test_descriptions_are_sentences() -> None:
    for topic, team, data in demo_data()["events"]:
        text = describe_event(LogEntry(0.0, topic, team, data))
        assert text and "{" not in text
    assert fmt_clock(None) == "--:--" and fmt_clock(61) == "01:01" and fmt_clock(3661) == "1:01:01"
    fault = describe_event(LogEntry(0.0, "core.storage", None, {"ok": False, "message": "the core cannot write"}))
    back = describe_event(LogEntry(0.0, "core.storage", None, {"ok": True, "message": "written again"}))
    assert fault.startswith("STORAGE FAULT: the core cannot write") and back.startswith("storage OK again")


def test_link_refuses_requests_while_down_and_reports_states(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """No core at all: requests fail at once with a sentence, the link keeps trying."""
    states: list[LinkState] = []

    async def scenario() -> None:
        link = CoreLink("tcp://127.0.0.1:9", "token", on_state=lambda s, d, i: states.append(s))
        link.start()
        await asyncio.sleep(0.2)
        with pytest.raises(ConnectionLostError, match="reconnecting"):
            await link.request("robots")
        await link.close()

    asyncio.run(scenario())
    assert states[0] is LinkState.CONNECTING and states[-1] is LinkState.CLOSED


def test_link_requests_run_side_by_side(core) -> None:  # type: ignore[no-untyped-def]
    """Many requests in flight on one socket; each gets its own reply."""
    async def scenario() -> None:
        link = CoreLink(str(core.state), core.token("red"))
        link.start()
        for _ in range(100):
            if link.connected:
                break
            await asyncio.sleep(0.05)
        replies = await asyncio.gather(*(link.request(t) for t in ("robots", "snapshot", "score", "arena") * 5))
        assert [sorted(r)[:1] for r in replies[:4]] == [["robots"], ["arena"], ["duration"], ["camera"]]
        with pytest.raises(NotYoursError, match="999"):  # refusals come back as the matching error
            await link.request("stop", tag=999)
        await link.close()

    asyncio.run(scenario())

"""One visibility table for every public feed, live and replayed (docs/security.md, "Public feeds").

A recorded match holds an event of every topic, each with every private field filled with a
marker; its public views (a web replay's public view and a replay core's PUB socket, read with
raw pyzmq) must carry none of the markers and none of the private topics, while carrying the
public topics (so the test can fail).
"""
from __future__ import annotations

import ast
import asyncio
import json
import time
from pathlib import Path
from typing import Any

import pytest
import zmq

from conftest import wait_for
from robo_comp import protocol as P
from robo_comp.core.eventlog import EventLog
from robo_comp.launch import _spawn
from robo_comp.world.public import arena_payload
from robo_comp.world.scenario import bundled_scenario_path, load_scenario

SECRET = "PRIVATE-MARKER"
T0 = 1_700_000_000.0
#: Seconds before the first event after ``core.started`` (the subscriber connects meanwhile).
LEAD = 3.0


def every_topic() -> list[tuple[str, str | None, dict[str, Any]]]:
    """One event of every topic, shaped as the core logs it, with every private field of its topic
    (what the table keeps from the public) a marker."""
    pos = {"tags": [101, 201], "x": [2.0, 20.0], "y": [8.0, 2.0], "heading": [0.0, 90.0], "moving": [True, False]}
    events: dict[str, tuple[str | None, dict[str, Any]]] = {
        "robot.registered": ("red", {"tag": 101, "team": "red", "robot_id": SECRET, "x": 2, "y": 8, "heading": 0,
                                     "tasks": []}),
        "robot.positions": (None, pos),
        "robot.lost": ("red", {"tag": 101, "x": 2, "y": 8, "message": SECRET}),
        "robot.returned": ("red", {"tag": 101, "x": 2, "y": 8}),
        "task.given": ("red", {"tag": 101, "task_id": 1, "name": "goTo", "args": [SECRET], "mode": "now", "by": "red"}),
        "task.started": ("red", {"tag": 101, "task_id": 1, "name": "goTo", "args": [SECRET]}),
        "task.done": ("red", {"tag": 101, "task_id": 1, "name": "goTo", "ok": True, "status": SECRET,
                              "result": {"x": SECRET}, "state": "done"}),
        "robot.stopped": ("red", {"tag": 101, "x": 2, "y": 8, "cancelled": [SECRET]}),
        "radio": ("red", {"from": 101, "to": [102], "data": SECRET, "delivered": [102]}),
        "refused": ("red", {"by": "red", "type": "give", "code": SECRET, "message": SECRET}),
        "core.storage": (None, {"ok": True, "seconds": 1.0, "message": SECRET}),
        "match.phase": (P.EVERYONE, {"phase": "running", "elapsed": 0.0, "duration": 600, "action": "start",
                                     "by": "referee", "was": "setup"}),
        "score": (P.EVERYONE, {"teams": [], "phase": "running"}),
        "match.clock": (None, {"phase": "running", "elapsed": 1.0, "remaining": 599.0, "duration": 600,
                               "outage": "pause", "boot": 1.0, "boot_id": SECRET}),
        "score.change": ("red", {"team": "red", "points": 1, "kind": "find", "reason": "victim found", "t": 1.0}),
        "penalty": ("red", {"team": "red", "points": -1, "reason": "bump"}),
        "disqualified": (P.EVERYONE, {"team": "blue", "tags": [201], "reason": "rules"}),
        "broadcast": (P.EVERYONE, {"message": "hello", "by": "referee"}),
        "find.reported": ("red", {"id": 1, "team": "red", "tag": 101, "x": 5, "y": 8, "kind": "victim",
                                  "state": "confirmed", "evidence": [SECRET], "message": SECRET}),
        "picture": ("red", {"id": 1, "tag": 101, "team": "red", "x": 4, "y": 8, "heading": 0, "t": T0,
                            "victims": [SECRET], "sha256": SECRET}),
        "robot.bump": ("red", {"tag": 101, "team": "red", "x": 2, "y": 8}),
        "robot.tasks": ("red", {"tag": 101, "tasks": [{"name": SECRET}]}),
        "robot.log": ("red", {"tag": 101, "stream": "stdout", "text": SECRET}),
        "upload.pending": ("red", {"upload_id": 1, "team": "red", "tags": [101], "filename": SECRET,
                                   "sha256": SECRET, "by": "red"}),
        "upload.sent": ("red", {"tags": [101], "filename": SECRET, "sha256": SECRET}),
        "upload.done": ("red", {"upload_id": 1, "team": "red", "tags": [101], "ok": False, "message": SECRET}),
        "upload.unloaded": ("red", {"tags": [101], "name": SECRET}),
        "sandbox.reset": ("red", {"tags": [101], "by": "referee", "results": [{"tag": 101, "note": SECRET}]}),
        "robot.left": ("red", {"tag": 101, "x": 2, "y": 8}),
        "integrity": (None, {"kind": "pose", "tag": 101, "team": "red", "count": 1, "x": 2, "y": 8,
                             "message": SECRET}),
        "robot.handover": ("red", {"tag": 101, "by": "referee", "from": SECRET}),
        "task.offered": ("red", {"tag": 101, "team": "red", "reallocate": True, "message": SECRET,
                                 "tasks": [{"task_id": 1, "name": "goTo", "args": [SECRET], "to": 102}]}),
        "teamwork": ("red", {"team": "red", "reallocate": True, "by": SECRET}),
        "map.obstacle": ("red", {"tag": 101, "team": "red", "x": SECRET, "y": SECRET}),
        "video": ("red", {"id": 1, "tag": 101, "team": "red", "x": 4, "y": 8, "heading": 0, "t": T0, "seconds": 5.0,
                          "frames": SECRET, "label": SECRET, "sha256": SECRET}),
        # team code's debug drawing: the team's own (this match's debug_replay is the default, "team")
        "debug.draw": ("red", {"team": "red", "tags": [101], "frames": [[["t", 2.0, 8.0, SECRET, "#ffffff"]]]}),
    }
    out = []
    for topic in P.TOPICS:
        if topic in ("core.started", "core.recovered"):
            continue  # the recording's start; a replay does not publish them again
        team, data = events[topic]
        row = P.TABLE[topic]
        if not row.private:  # every field the table keeps from the public, also those this sample lacks
            data = {**data, **{k: SECRET for k in row.fields - set(row.public)}}
        out.append((topic, team, data))
    assert {t for t, _, _ in out} | {"core.started", "core.recovered"} == set(P.TOPICS)
    return out


def write_every_topic(path: Path) -> list[str]:
    """The recording: the demo room, then every topic once; returns the topics in order."""
    sc = load_scenario(bundled_scenario_path("demo_room"))
    path.parent.mkdir(parents=True, exist_ok=True)
    log = EventLog(path)
    log.append("core.started", None, {"router": "tcp://x", "teams": ["red", "blue"],
                                      "arena": arena_payload(sc, ["red", "blue"])}, t=T0)
    log.append("robot.registered", "blue", {"tag": 201, "team": "blue", "robot_id": "b1", "x": 20, "y": 2,
                                            "heading": 90}, t=T0 + 0.1)
    topics = []
    for i, (topic, team, data) in enumerate(every_topic()):
        log.append(topic, team, data, t=T0 + LEAD + 0.05 * i)
        topics.append(topic)
    log.close()
    return topics


def leaks(frames: list[tuple[str, str]]) -> list[tuple[str, str]]:
    return [(t, text) for t, text in frames if SECRET in text or t in P.PRIVATE_TOPICS]


def test_the_table_is_the_one_place_that_decides_visibility() -> None:
    """Every topic is public or private in the table, and nothing else decides: no place that
    emits an event says whether it is public (the core emits each event once, and the table
    strips a public topic's private fields, as a ``picture``'s victims)."""
    assert set(P.TOPICS) == P.PUBLIC_TOPICS.keys() | P.PRIVATE_TOPICS
    assert not P.PUBLIC_TOPICS.keys() & P.PRIVATE_TOPICS
    assert P.public_event("not.a.topic", {"x": 1}) is None  # a topic nobody listed is private
    # the referee's broadcast reaches the public feeds with its message, and with nothing else
    assert P.public_event("broadcast", {"message": "hi", "by": "referee", "x": 1}) == {"message": "hi", "by": "referee"}
    root = Path(P.__file__).parents[1]
    emits = 0
    for f in root.rglob("*.py"):
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "emit" and node.args \
                    and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str):
                emits += 1
                assert not any(k.arg == "public" for k in node.keywords), (f.name, node.lineno)
    assert emits >= 30


def test_the_table_says_what_is_wrong_with_an_event() -> None:
    """``check_event`` (which the tests run on every event a core logs) finds each kind of fault."""
    good = {"tag": 101, "task_id": 1, "name": "goTo", "args": [1, 2]}
    assert P.check_event("task.started", good) is None
    assert "not a topic" in P.check_event("task.begun", good)
    assert "without task_id" in P.check_event("task.started", {k: v for k, v in good.items() if k != "task_id"})
    assert "not in the table: colour" in P.check_event("task.started", dict(good, colour="red"))
    assert "not a map" in P.check_event("task.started", [1, 2])


def test_a_web_replay_with_every_topic_shows_nothing_private(tmp_path: Path) -> None:
    pytest.importorskip("starlette", reason="the web extra is not installed (pip install -e '.[web]')")
    from robo_comp.web.replay import Recording

    log = tmp_path / "m" / "events.log"
    topics = write_every_topic(log)
    rec = Recording(log)
    view = asyncio.run(rec.view("public"))
    frames = [(json.loads(f)[0], f) for f in view.frags] + [("state", k) for k in view.key_json]
    assert not leaks(frames), leaks(frames)[:5]
    shown = {t for t, _ in frames}
    assert {t for t in topics if t in P.PUBLIC_TOPICS} - {"robot.positions"} <= shown  # the public ones are there
    referee = asyncio.run(rec.view("referee"))  # the referee's view of the same replay holds the markers
    assert any(SECRET in f for f in referee.frags)


def test_a_replay_core_publishes_nothing_private(tmp_path: Path) -> None:
    """``robo-comp replay``: its PUB socket, read with raw pyzmq, carries the public topics only,
    and none of their private fields (before, it published every logged event whole)."""
    log = tmp_path / "m" / "events.log"
    topics = write_every_topic(log)
    state = tmp_path / "replay"
    state.mkdir()
    proc = _spawn(["replay", str(log), "--state", str(state), "--exit-at-end"], state / "replay.log")
    ctx = zmq.Context()
    sub = ctx.socket(zmq.SUB)
    got: list[tuple[str, str]] = []
    try:
        wait_for(lambda: (state / "core.json").exists() or proc.poll() is not None, 20, "the replay to start")
        assert proc.poll() is None, (state / "replay.log").read_text()
        sub.setsockopt(zmq.SUBSCRIBE, b"")
        sub.connect(json.loads((state / "core.json").read_text())["pub"])
        end = time.monotonic() + LEAD + 0.05 * len(topics) + 30
        while time.monotonic() < end:  # until the replay has played everything and exited
            if sub.poll(200):
                topic, body = sub.recv_multipart()
                got.append((topic.decode(), json.dumps(P.unpack(body), default=str)))
            elif proc.poll() is not None:
                break
    finally:
        sub.close(0)
        ctx.term()
        proc.terminate()
        proc.wait(10)
    assert proc.returncode == 0, (state / "replay.log").read_text()[-2000:]
    assert not leaks(got), leaks(got)[:5]
    assert {t for t in topics if t in P.PUBLIC_TOPICS} <= {t for t, _ in got}


def mcap_messages(path: Path) -> list[tuple[str, str]]:
    """Every message of an MCAP file, decoded, as (topic, its text: JSON, or an image's bytes)."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    out = []
    with open(path, "rb") as f:
        for _, channel, _, m in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            data = getattr(m, "data", None)
            out.append((channel.topic, data if isinstance(data, str) else  # JSON (std_msgs/String)
                        bytes(data).decode("latin-1") if channel.topic == "/pictures" else str(m)))
    return out


def test_a_public_mcap_export_carries_nothing_private(tmp_path: Path) -> None:
    """``robo-comp export mcap`` (its default view, public): no marker in any message, no private
    topic on ``/events``, no picture's image; the public topics are there. Before, the export wrote
    every record whole and every picture."""
    pytest.importorskip("mcap_ros2", reason="the mcap extra is not installed (pip install -e '.[mcap]')")
    from robo_comp.export.mcap import export_mcap

    log = tmp_path / "m" / "events.log"
    topics = write_every_topic(log)
    (log.parent / "pictures").mkdir()
    (log.parent / "pictures" / "1.png").write_bytes(b"\x89PNG\r\n\x1a\n" + SECRET.encode())  # red's picture 1
    export_mcap(log, tmp_path / "public.mcap")
    got = mcap_messages(tmp_path / "public.mcap")
    assert not [m for m in got if SECRET in m[1]], [m for m in got if SECRET in m[1]][:5]
    events = [json.loads(text) for t, text in got if t == "/events"]
    assert not {e["topic"] for e in events} & P.PRIVATE_TOPICS
    assert {e["topic"] for e in events} == {"core.started", *(t for t in topics if t in P.PUBLIC_TOPICS)}
    assert "/pictures" not in {t for t, _ in got}
    # the team's and the referee's views of the same log hold the markers and the picture
    export_mcap(log, tmp_path / "red.mcap", view="team:red")
    red = mcap_messages(tmp_path / "red.mcap")
    assert any(SECRET in text for t, text in red if t == "/pictures") and any(SECRET in m[1] for m in red)
    export_mcap(log, tmp_path / "blue.mcap", view="team:blue")
    blue = mcap_messages(tmp_path / "blue.mcap")
    assert {json.loads(text)["team"] for t, text in blue if t == "/events"} <= {"blue", P.EVERYONE, None}
    assert "/pictures" not in {t for t, _ in blue}  # red's picture


def test_the_viewers_fold_only_what_the_table_describes() -> None:
    """The wall's and web's fold (view.MatchView) and the consoles' model take parsing from the
    topic table: an event lacking what its topic always carries is skipped, not folded (and does
    not crash the viewer); a public view of an event (its private fields left out) is folded."""
    from robo_comp.tui.model import ConsoleModel
    from robo_comp.view.model import MatchView

    full = {"tag": 101, "team": "red", "robot_id": "red-1", "x": 2.0, "y": 8.0, "heading": 0.0, "tasks": []}
    public = P.public_event("robot.registered", full)
    broken = {"team": "red", "x": 2.0}  # no tag: a damaged record, or a hostile log
    assert P.readable("robot.registered", full) and P.readable("robot.registered", public)
    assert not P.readable("robot.registered", broken) and not P.readable("robot.registered", [1])
    view = MatchView()
    view.apply("robot.registered", broken)
    view.apply("robot.lost", {"x": 1})
    assert view.robots == {} and view.skipped == 2
    view.apply("robot.registered", public)
    assert list(view.robots) == [101]
    console = ConsoleModel()
    assert console.apply("robot.registered", "red", broken) is None and console.robots == {}
    console.apply("robot.registered", "red", full)
    assert list(console.robots) == [101]

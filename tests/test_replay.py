"""``robo-comp replay``: a recorded match served like a live one, read-only, at any speed."""
from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import pytest

import robo_comp.world.scenario as scen
from conftest import next_event_where, wait_for, wait_robots
from robo_comp.client import Client
from robo_comp.protocol.curve import ENV_CERT, ENV_CORE_KEY, create_keys
from robo_comp.errors import ConnectionLostError, FieldError, ForbiddenError, TimeoutError_
from robo_comp.launch import _spawn, start_core, start_robots, stop_all
from robo_comp.core.replay import ReplayCore

DEMO = Path(scen.__file__).parent / "scenarios" / "demo_room.toml"


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A short practice match on demo_room: two red robots drive somewhere, one blue robot."""
    state = tmp_path_factory.mktemp("match") / "state"
    core = start_core(state, "--heartbeat", "0.2", "--scenario", str(DEMO), "--practice")
    procs = [core, start_robots(state, "red", 2, "--speed", "6"), start_robots(state, "blue", 1)]
    try:
        red = Client(str(state), (state / "teams" / "red.token").read_text().strip())
        red.watch(True)
        rows = wait_robots(red, 2)
        done = []
        for row, target in zip(rows, ([3, 3], [6, 4])):
            tid = red.give(row["tag"], "goTo", target)["task_id"]
            done.append(next_event_where(red, lambda e, t=tid: e["topic"] == "task.done"
                                         and e["data"]["task_id"] == t, 20)["data"])
        time.sleep(0.5)
        final = {r["tag"]: (r["x"], r["y"]) for r in red.robots()}
        red.close()
    finally:
        stop_all(procs)
    return state, rows, done, final


def start_replay(log: Path, state: Path, *extra: str):
    state.mkdir(parents=True, exist_ok=True)
    proc = _spawn(["replay", str(log), "--state", str(state), *extra], state / "replay.log")
    wait_for(lambda: (state / "core.json").exists() or proc.poll() is not None, 20, "the replay to start")
    assert proc.poll() is None, (state / "replay.log").read_text()
    return proc


def test_consoles_follow_a_replay_like_a_live_match_and_cannot_command_it(recorded, tmp_path):
    match, rows, done, final = recorded
    proc = start_replay(match / "events.log", tmp_path / "replay", "--speed", "4")
    try:
        # the match's own tokens work: red sees red's robots, the referee sees all
        red = Client(str(tmp_path / "replay"), (match / "teams" / "red.token").read_text().strip())
        ref = Client(str(tmp_path / "replay"), (match / "referee.token").read_text().strip())
        red.watch(True)
        seen = []
        while len([e for e in seen if e["topic"] == "task.done"]) < 2:
            ev = red.next_event(10)
            assert ev is not None, f"no more events; got {[e['topic'] for e in seen]}"
            seen.append(ev)
        topics = {e["topic"] for e in seen}
        assert {"robot.registered", "task.given", "task.started", "robot.positions"} <= topics
        assert not any(e["data"].get("team") == "blue" for e in seen)  # team views stay private
        got = [e["data"] for e in seen if e["topic"] == "task.done"]
        assert [(d["task_id"], d["ok"]) for d in got] == [(d["task_id"], d["ok"]) for d in done]
        assert {r["tag"] for r in red.robots()} == {r["tag"] for r in rows}
        assert len(ref.robots()) == 3
        assert red.tasks(rows[0]["tag"])["done"][0]["task_id"] == done[0]["task_id"]
        assert "teams" in ref.score()
        with pytest.raises(ForbiddenError, match="read-only"):
            red.give(rows[0]["tag"], "goTo", [2, 2])
        with pytest.raises(ForbiddenError, match="read-only"):
            ref.request("match", action="pause")
        red.close()
        ref.close()
    finally:
        stop_all([proc])


def test_a_fast_replay_ends_where_the_match_ended(recorded, tmp_path):
    match, rows, done, final = recorded
    proc = start_replay(match / "events.log", tmp_path / "replay", "--speed", "50", "--exit-at-end")
    try:
        assert proc.wait(30) == 0
    finally:
        stop_all([proc])
    # in-process: the state after the whole recording is the match's final state
    core = ReplayCore(match / "events.log", tmp_path / "again")
    core.play(core.duration + 1, publish=False)
    for tag, (x, y) in final.items():
        r = core.registry.robots[tag]
        assert abs(r.x - x) < 1.0 and abs(r.y - y) < 1.0
    assert len(core.registry.robots) == 3


def test_a_replay_of_a_networked_match_takes_the_matchs_keys(recorded, tmp_path, monkeypatch):
    monkeypatch.delenv(ENV_CERT, raising=False)
    monkeypatch.delenv(ENV_CORE_KEY, raising=False)
    match = tmp_path / "match"  # the recorded match, as if it had run with --curve: keys beside its log
    shutil.copytree(recorded[0], match, ignore=shutil.ignore_patterns("core.json", "*.log.*"))
    create_keys(match, ["red", "blue"])
    replay = tmp_path / "replay"
    proc = start_replay(match / "events.log", replay, "--curve", "--speed", "10")
    try:
        info = json.loads((replay / "core.json").read_text())
        assert info["curve"] is True
        assert (replay / "keys" / "red.key_secret").read_bytes() == (match / "keys" / "red.key_secret").read_bytes()
        red_token = (match / "teams" / "red.token").read_text().strip()
        red = Client(str(replay), red_token, timeout=5.0)  # red's certificate, found in the state folder
        assert red.curve is not None
        wait_robots(red, 2)
        # no certificate: no handshake, no reply (said at once when the handshake fails with a reason)
        with pytest.raises((TimeoutError_, ConnectionLostError), match="--curve"):
            Client(info["router"], red_token, timeout=1.0)
        assert len(red.robots()) == 2  # the replay kept serving
        red.close()
    finally:
        stop_all([proc])


def test_bad_logs_are_refused_with_a_sentence(tmp_path):
    with pytest.raises(FieldError, match="no such event log"):
        ReplayCore(tmp_path / "nope.log", tmp_path / "r")
    junk = tmp_path / "junk.log"
    junk.write_bytes(b"\x00\x00\x00\x05hello")
    with pytest.raises(FieldError, match="no core.started"):
        ReplayCore(junk, tmp_path / "r2")

"""Crash recovery: kill -9 the core, start it again on the same state, lose nothing."""
from __future__ import annotations

import json
import os
import random
import signal
from pathlib import Path

import pytest

from conftest import wait_robots
from robo_comp.client import Client
from robo_comp.protocol.logfile import LogCorrupt, pack_record, read_log
from robo_comp.launch import start_core, start_robots, stop_all

import robo_comp.world.scenario as scen

DEMO = Path(scen.__file__).parent / "scenarios" / "demo_room.toml"


def _kill9(proc):
    proc.send_signal(signal.SIGKILL)
    proc.wait()


def _port(state: Path) -> int:
    return int(json.loads((state / "core.json").read_text())["router"].rsplit(":", 1)[1])


def test_kill_9_restores_tags_queues_scores_phase_and_robots_keep_their_tags(tmp_path):
    state = tmp_path / "s"
    core = start_core(state, "--heartbeat", "0.3", "--scenario", str(DEMO))
    procs = [core]
    try:
        procs.append(start_robots(state, "red", 2, "--scenario", str(DEMO), "--speed", "0.5"))
        red = Client(str(state), (state / "teams/red.token").read_text().strip())
        ref = Client(str(state), (state / "referee.token").read_text().strip())
        rows = wait_robots(red, 2)
        tags = {r["robot_id"]: r["tag"] for r in rows}
        t0 = rows[0]["tag"]
        ref.request("match", action="start")
        cur = red.give(t0, "goTo", [20, 12])["task_id"]
        q1 = red.give(t0, "goTo", [2, 2], queue=True)["task_id"]
        q2 = red.give(t0, "examineArea", [3, 3], queue=True)["task_id"]
        ref.request("penalty", team="red", points=4, reason="test")
        ref.request("disqualify", tag=rows[1]["tag"], reason="test")
        before = ref.request("score")
        red.close()
        ref.close()
        port = _port(state)
        _kill9(core)
        core = start_core(state, "--heartbeat", "0.3", "--scenario", str(DEMO), port=port)
        procs[0] = core
        red = Client(str(state), (state / "teams/red.token").read_text().strip())
        ref = Client(str(state), (state / "referee.token").read_text().strip())
        after = ref.request("score")
        assert after["phase"] == "running"
        assert after["elapsed"] >= before["elapsed"]
        assert [(t["team"], t["score"], t["disqualified"]) for t in after["teams"]] == \
               [(t["team"], t["score"], t["disqualified"]) for t in before["teams"]]
        # the robot host reconnects on its own: same robot ids, same tags, task carried on
        rows = wait_robots(red, 1, timeout=15)
        assert {r["robot_id"]: r["tag"] for r in red.robots()} == tags
        t = red.tasks(t0)
        assert t["current"]["task_id"] == cur
        assert [q["task_id"] for q in t["queued"]] == [q1, q2]
        assert {r["tag"]: r["status"] for r in red.robots()}[tags["red-2"]] == "disqualified"
        assert "goTo" in {a["name"] for a in t["advertised"]}
        red.close()
        ref.close()
    finally:
        stop_all(procs)


def test_acknowledged_events_survive_kill_9_at_random_points(tmp_path):
    """Every task the core acknowledged before the kill is still known after recovery."""
    state = tmp_path / "s"
    rng = random.Random(5)
    core = start_core(state, "--heartbeat", "0.3")
    procs = [core]
    acked: list[int] = []
    try:
        procs.append(start_robots(state, "red", 3))
        for cycle in range(4):
            red = Client(str(state), (state / "teams/red.token").read_text().strip(), timeout=5)
            rows = wait_robots(red, 3, timeout=15)
            for _ in range(rng.randrange(5, 40)):
                r = rng.choice(rows)
                acked.append(red.give(r["tag"], "goTo", [rng.randrange(1, 20), rng.randrange(1, 15)],
                                      queue=True)["task_id"])
            # fire more without waiting for the replies, then kill at once
            for _ in range(rng.randrange(0, 20)):
                red.sock.send(__import__("robo_comp.protocol", fromlist=["x"]).request(
                    "give", 9999, {"tag": rows[0]["tag"], "task": "goTo", "args": [1, 1], "queue": True},
                    red.session))
            red.close()
            port = _port(state)
            _kill9(core)
            core = start_core(state, "--heartbeat", "0.3", port=port)
            procs[0] = core
        red = Client(str(state), (state / "teams/red.token").read_text().strip())
        known = set()
        for r in red.robots():
            t = red.tasks(r["tag"])
            known |= {x["task_id"] for x in t["queued"] + t["done"]}
            if t["current"]:
                known.add(t["current"]["task_id"])
        # done lists keep the newest 20 per robot; nothing acknowledged may be missing
        missing = [a for a in acked if a not in known]
        assert not missing, f"{len(missing)} acknowledged tasks lost: {missing[:10]}"
        red.close()
    finally:
        stop_all(procs)


def test_truncated_and_corrupt_tails_are_reported_and_the_rest_recovers(tmp_path):
    state = tmp_path / "s"
    core = start_core(state, "--heartbeat", "0.3")
    try:
        c = Client(str(state), (state / "referee.token").read_text().strip())
        c.close()
        robots = start_robots(state, "blue", 2)
        blue = Client(str(state), (state / "teams/blue.token").read_text().strip())
        tags = sorted(r["tag"] for r in wait_robots(blue, 2))
        blue.close()
        stop_all([robots])
        port = _port(state)
    finally:
        _kill9(core)
    log = state / "events.log"
    good = len(list(read_log(log)))
    with open(log, "ab") as f:  # a torn record at the end (an unfinished write)
        f.write(pack_record({"seq": 10**6, "t": 0.0, "topic": "x", "team": None, "data": {"pad": "y" * 100}})[:60])
    with pytest.raises(LogCorrupt, match="truncated record"):
        list(read_log(log))
    core = start_core(state, "--heartbeat", "0.3", port=port)
    try:
        ref = Client(str(state), (state / "referee.token").read_text().strip())
        ref.watch(True)
        assert sorted(r["tag"] for r in ref.robots()) == tags
        info = ref.request("stats")
        assert info["log_seq"] >= good
        ref.close()
        recs = list(read_log(log))  # the tail was cut off: the log reads cleanly again
        rec = next(r for r in recs if r.topic == "core.recovered")
        assert "truncated record" in rec.data["damage"] and os.path.exists(rec.data["damaged_copy"])
        assert "cut off" in rec.data["damage"] and rec.data["damages"][0]["tail"]
    finally:
        stop_all([core])

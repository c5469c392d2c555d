"""The public feed under load: positions are conflated into one batch per team per pose period."""
from __future__ import annotations

import json
import time

import msgpack
import pytest
import zmq

from robo_comp.client import recv_event
from robo_comp import protocol as P
from robo_comp.protocol.curve import secure_plain_client

POSE_HZ = 5


class Host:
    """A raw robot host (DEALER) that registers robots and floods the core with reports."""

    def __init__(self, url: str, token: str) -> None:
        self.s = zmq.Context.instance().socket(zmq.DEALER)
        self.s.setsockopt(zmq.LINGER, 0)
        self.s.setsockopt(zmq.ROUTING_ID, P.new_routing_id())
        secure_plain_client(self.s, token)  # the core lets in no connection without a token
        self.s.connect(url)
        self.token = token
        self.sid = None  # the session secret, from the first register's reply

    def ask(self, type_: str, req_id: int, body: dict, timeout: float = 1.0) -> dict | None:
        """The reply to request ``req_id``, or None when none comes within ``timeout`` (what
        else the core sends a host, heartbeats and map deltas, is skipped)."""
        self.s.send(P.request(type_, req_id, body, self.sid))
        end = time.monotonic() + timeout
        while self.s.poll(max(0.0, end - time.monotonic()) * 1000):
            msg = msgpack.unpackb(self.s.recv(), raw=False)
            if msg["type"] == "reply" and msg["id"] == req_id:
                self.sid = self.sid or (msg.get("body") or {}).get("session")
                return msg
        return None

    def register(self, robot_id: str) -> int:
        reply = self.ask("register", 1, {"token": self.token, "robot_id": robot_id, "tasks": []}, 5.0)
        assert reply is not None and reply["ok"], reply
        return reply["body"]["tag"]

    def report(self, tag: int, x: float) -> None:
        self.s.send(P.request("report", 0, {"tag": tag, "x": x, "y": 2.5, "heading": 90.0, "moving": True}, self.sid))

    def close(self) -> None:
        self.s.close(0)


@pytest.mark.core_args("--pose-hz", str(POSE_HZ))
def test_reports_reach_subscribers_conflated_per_team(core):
    url = json.loads((core.state / "core.json").read_text())["router"]
    red, blue = Host(url, core.host_token("red")), Host(url, core.host_token("blue"))
    ref = core.client("referee")
    feed = ref.subscribe("robot.position")  # the prefix of robot.positions
    blue_console = core.client("blue")
    blue_console.watch()
    try:
        red_tags = [red.register(f"r{i}") for i in range(3)]
        blue_tags = [blue.register(f"b{i}") for i in range(2)]
        time.sleep(0.3)  # the SUB socket's subscription reaches the core
        for step in range(1, 201):  # 200 reports per robot within about one second
            for tag in red_tags:
                red.report(tag, 1.0 + step / 100)
            for tag in blue_tags:
                blue.report(tag, 1.0 + step / 100)
            time.sleep(0.005)
        batches: list[tuple[str, dict]] = []
        while feed.poll(1000):  # the last batch leaves at most one pose period after the last report
            batches.append(recv_event(feed))
    finally:
        red.close()
        blue.close()
    assert {topic for topic, _ in batches} == {"robot.positions"}
    by_team = {"red": [d for _, d in batches if d["team"] == "red"],
               "blue": [d for _, d in batches if d["team"] == "blue"]}
    for team, tags in (("red", red_tags), ("blue", blue_tags)):
        got = by_team[team]
        assert got, f"no positions for {team}"
        # conflated: far fewer batches than the 200 reports each robot sent (5 batches a second
        # over the one to a few seconds the reporting takes)
        assert len(got) < 200 / 4
        for d in got:
            assert set(d["tags"]) <= set(tags)
            assert len(d["tags"]) == len(d["x"]) == len(d["y"]) == len(d["heading"]) == len(d["moving"])
        # every robot's newest pose reaches the feed: its last batch carries its last report (a batch
        # carries the robots that moved since the one before, so when a pose period ends between
        # two robots' last reports, the last batch holds only the later ones)
        newest = {tag: x for d in got for tag, x in zip(d["tags"], d["x"])}
        assert newest == {tag: 3.0 for tag in tags}
        assert set(got[-1]["tags"]) <= set(tags) and got[-1]["x"] == [3.0] * len(got[-1]["tags"])
    # a team's console is pushed its own team's batches only
    pushed = []
    while (ev := blue_console.next_event(0.5)) is not None:
        pushed.append(ev)
    positions = [e for e in pushed if e["topic"] == "robot.positions"]
    assert positions and all(e["team"] == "blue" and set(e["data"]["tags"]) <= set(blue_tags) for e in positions)


def test_a_batch_of_reports_is_checked_row_by_row_and_keeps_the_good_rows(core):
    url = json.loads((core.state / "core.json").read_text())["router"]
    red, blue = Host(url, core.host_token("red")), Host(url, core.host_token("blue"))
    ref = core.client("referee")
    try:
        mine = [red.register(f"r{i}") for i in range(2)]
        theirs = blue.register("b0")

        def send(req_id: int, body: dict) -> dict | None:
            return red.ask("reports", req_id, body)

        good = {"tags": mine, "x": [2.0, 3.0], "y": [2.5, 2.5], "heading": [0.0, 90.0], "moving": [True, False]}
        assert send(1, good) is None  # a notification: no reply when all is well
        bad_rows = [
            ({**good, "x": [2.0]}, "one 'x' per tag"),
            ({**good, "y": [2.5, float("nan")]}, "'y'[1]"),
            ({**good, "tags": [mine[0], "r1"]}, "'tags'[1]"),
            ({**good, "moving": [True, 1]}, "'moving'[1]"),
            ({**good, "sensors": [None, [1, 2]]}, "'sensors'[1]"),
            ({**good, "heading": 90.0}, "must be list"),
        ]
        for i, (body, words) in enumerate(bad_rows, start=2):
            reply = send(i, body)
            assert reply is not None and reply["ok"] is False, body
            assert reply["error"]["code"] == "E_FIELD" and words in reply["error"]["message"], reply
        # another host's robot in the batch: refused by name, the host's own rows are taken
        mixed = {"tags": [mine[0], theirs], "x": [5.0, 5.0], "y": [4.0, 4.0], "heading": [0.0, 0.0]}
        reply = send(20, mixed)
        assert reply["error"]["code"] == "E_NOT_YOURS" and str(theirs) in reply["error"]["message"]
        rows = {r["tag"]: r for r in ref.robots()}
        assert (rows[mine[0]]["x"], rows[mine[0]]["y"]) == (5.0, 4.0)
        assert (rows[mine[1]]["x"], rows[mine[1]]["heading"]) == (3.0, 90.0)  # from the good batch
        assert rows[theirs]["x"] != 5.0
    finally:
        red.close()
        blue.close()


@pytest.mark.core_args("--pose-hz", "2")
def test_a_robot_that_left_is_not_in_the_next_positions_batch(core):
    url = json.loads((core.state / "core.json").read_text())["router"]
    red = Host(url, core.host_token("red"))
    feed = core.client("referee").subscribe()
    try:
        stays, leaves = red.register("r0"), red.register("r1")
        time.sleep(0.6)  # the subscription is up and the registrations' batch is out
        while feed.poll(0):
            recv_event(feed)
        red.report(stays, 4.0)
        red.report(leaves, 5.0)
        reply = red.ask("leave", 2, {"tag": leaves})  # within the same pose period
        assert reply is not None and reply["ok"], reply
        seen = []
        while feed.poll(1500):
            seen.append(recv_event(feed))
    finally:
        red.close()
    topics = [t for t, _ in seen]
    assert "robot.left" in topics and "robot.positions" in topics
    batch = next(d for t, d in seen if t == "robot.positions")
    assert batch["tags"] == [stays] and batch["x"] == [4.0]

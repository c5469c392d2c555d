"""Team radio: robot to robot through the core, own team only, size and rate limited."""
from __future__ import annotations

import json

import msgpack
import pytest
import zmq

from robo_comp import protocol as P
from robo_comp.protocol.curve import secure_plain_client


class Host:
    """A minimal robot host on a raw DEALER socket."""

    def __init__(self, core, team: str, ids: list[str]) -> None:
        url = json.loads((core.state / "core.json").read_text())["router"]
        self.s = zmq.Context.instance().socket(zmq.DEALER)
        self.s.setsockopt(zmq.LINGER, 0)
        self.s.setsockopt(zmq.ROUTING_ID, P.new_routing_id())
        secure_plain_client(self.s, core.host_token(team))  # the core lets in no connection without a token
        self.s.connect(url)
        self.n = 0
        self.sid = None  # the session secret, from the first register's reply
        self.inbox: list[dict] = []
        self.tags = [self.ask("register", token=core.host_token(team), robot_id=i)["body"]["tag"] for i in ids]

    def ask(self, type_: str, **body) -> dict:
        self.n += 1
        self.s.send(P.request(type_, self.n, body, self.sid))
        while self.s.poll(3000):
            m = msgpack.unpackb(self.s.recv(), raw=False)
            if m["type"] == "reply" and m["id"] == self.n:
                self.sid = self.sid or (m.get("body") or {}).get("session")
                return m
            if m["type"] == "radio":
                self.inbox.append(m["body"])
        raise AssertionError("no reply")

    def drain(self) -> list[dict]:
        while self.s.poll(200):
            m = msgpack.unpackb(self.s.recv(), raw=False)
            if m["type"] == "radio":
                self.inbox.append(m["body"])
        return self.inbox


@pytest.mark.heartbeat(10)
def test_radio_reaches_own_team_only(core):
    red = Host(core, "red", ["a", "b"])
    red2 = Host(core, "red", ["c"])
    blue = Host(core, "blue", ["z"])
    watcher = core.client("red")
    watcher.watch(True)
    bwatch = core.client("blue")
    bwatch.watch(True)
    r = red.ask("radio", tag=red.tags[0], to=red2.tags[0], data={"victim": [3, 4]})
    assert r["ok"] and r["body"]["delivered"] == 1
    assert red2.drain()[-1] == {"from": red.tags[0], "to": red2.tags[0], "data": {"victim": [3, 4]},
                                "tag": red2.tags[0]}
    r = red.ask("radio", tag=red.tags[0], data="all")  # broadcast to the team
    assert r["body"]["delivered"] == 2
    r = red.ask("radio", tag=red.tags[0], to=blue.tags[0], data="psst")
    assert not r["ok"] and r["error"]["code"] == "E_NOT_YOURS"
    assert blue.drain() == []
    r = red.ask("radio", tag=blue.tags[0], data="spoof")  # cannot speak for another team's robot
    assert not r["ok"] and r["error"]["code"] == "E_NOT_YOURS"
    ev = watcher.next_event(2)
    while ev and ev["topic"] != "radio":
        ev = watcher.next_event(2)
    assert ev and ev["data"]["data"] == {"victim": [3, 4]}
    ev = bwatch.next_event(0.5)
    while ev:
        assert ev["topic"] != "radio"
        ev = bwatch.next_event(0.3)


@pytest.mark.heartbeat(10)
def test_radio_size_and_rate_limits(core):
    red = Host(core, "red", ["a", "b"])
    r = red.ask("radio", tag=red.tags[0], data="x" * (P.MAX_RADIO + 1))
    assert r["error"]["code"] == "E_TOO_LARGE"
    codes = [red.ask("radio", tag=red.tags[0], to=red.tags[1], data=i).get("error", {}).get("code")
             for i in range(int(P.RADIO_RATE) * 3)]
    assert "E_RATE" in codes
    assert codes.count(None) >= P.RADIO_RATE - 1 and codes.count(None) < len(codes)

"""The map service through the protocol: snapshots, pieces, and pushed deltas that keep a
robot host's map equal to the service's."""
from __future__ import annotations

import json
import time
from pathlib import Path

import msgpack
import pytest
import zmq

import robo_comp.world.scenario as scen
from conftest import CoreHandle, wait_for
from robo_comp import protocol as P
from robo_comp.protocol.curve import secure_plain_client
from robo_comp.errors import FieldError, NotYoursError
from robo_comp.launch import start_core
from robo_comp.world.mapservice import MapView

DEMO = Path(scen.__file__).parent / "scenarios" / "demo_room.toml"


@pytest.fixture
def practice(tmp_path):
    state = tmp_path / "state"
    proc = start_core(state, "--heartbeat", "0.3", "--scenario", str(DEMO), "--practice")
    h = CoreHandle(state, None, proc)
    yield h
    h.close()


class RawHost:
    """A robot host on a raw socket that keeps a MapView from the pushed deltas."""

    def __init__(self, core, team):
        url = json.loads((core.state / "core.json").read_text())["router"]
        self.s = zmq.Context.instance().socket(zmq.DEALER)
        self.s.setsockopt(zmq.LINGER, 0)
        self.s.setsockopt(zmq.ROUTING_ID, P.new_routing_id())
        secure_plain_client(self.s, core.host_token(team))  # the core lets in no connection without a token
        self.s.connect(url)
        self.n = 0
        self.sid = None  # the session secret, from the register reply
        self.view = MapView()
        self.deltas = 0
        self.tag = self.ask("register", token=core.host_token(team), robot_id="mapper", x=3, y=3)["body"]["tag"]

    def ask(self, type_, **body):
        self.n += 1
        self.s.send(P.request(type_, self.n, body, self.sid))
        t_end = time.monotonic() + 5.0
        while time.monotonic() < t_end and self.s.poll(1000):
            m = msgpack.unpackb(self.s.recv(), raw=False)
            if m["type"] == "reply" and m["id"] == self.n:
                self.sid = self.sid or (m.get("body") or {}).get("session")
                return m
            self._push(m)
        raise AssertionError("no reply")

    def _push(self, m):
        if m["type"] == "map.delta":
            self.view.apply(m["body"])
            self.deltas += 1

    def pump(self, seconds):
        t_end = time.monotonic() + seconds
        while (left := t_end - time.monotonic()) > 0:
            if self.s.poll(left * 1000):
                self._push(msgpack.unpackb(self.s.recv(), raw=False))

    def report(self, x, y):
        self.s.send(P.request("report", 0, {"tag": self.tag, "x": x, "y": y, "heading": 0.0}, self.sid))


def _same(view, snap):
    """The host's view equals the service's map, robot positions aside (they are not pushed)."""
    mine = view.snapshot()
    for key in ("walls", "costs", "objects", "discoveries", "width", "height"):
        assert mine[key] == snap[key], key


def test_pushed_deltas_keep_the_hosts_map_equal_to_the_service(practice):
    host = RawHost(practice, "red")
    red = practice.client("red")
    host.pump(0.5)
    assert host.deltas == 1  # the first push is the whole map
    for step in range(3):  # along the free cells (3..5, 3): a wall stands at (6, 3)
        host.report(3 + step, 3)
        host.s.send(P.request("heartbeat", 0, {}, host.sid))  # a notification: no reply
        host.pump(0.4)
    assert host.deltas == 1  # robots moving change no host's map: nothing is pushed
    snap = red.request("map")
    assert [(r["x"], r["y"]) for r in snap["robots"] if r["tag"] == str(host.tag)] == [(5.0, 3.0)]
    r = host.ask("find", tag=host.tag, x=9, y=5, kind="victim")  # a (false) report still marks the map
    assert r["ok"]
    host.pump(0.8)
    assert host.deltas == 2
    snap = red.request("map")
    assert snap["version"] >= host.view.version > 1
    _same(host.view, snap)
    assert any(d["x"] == 9 and d["y"] == 5 for d in host.view.snapshot()["discoveries"])


def test_discoveries_belong_to_their_team_and_pieces_mark_shared_areas(practice):
    red_host = RawHost(practice, "red")
    blue = practice.client("blue")
    red = practice.client("red")
    red_host.ask("find", tag=red_host.tag, x=9, y=5, kind="victim")
    assert red.request("map")["discoveries"] and blue.request("map")["discoveries"] == []
    assert practice.client("referee").request("map")["discoveries"]
    piece = red.request("map", tag=red_host.tag, radius=2)
    assert piece["type"] == "piece" and piece["width"] == 5 and "shared" in piece
    with pytest.raises(NotYoursError):
        blue.request("map", tag=red_host.tag, radius=2)
    with pytest.raises(FieldError, match="radius"):
        red.request("map", tag=red_host.tag, radius=1000)


def test_non_finite_positions_are_refused(practice):
    host = RawHost(practice, "red")
    host.n += 1
    host.s.send(P.request("report", host.n, {"tag": host.tag, "x": float("nan"), "y": 1.0, "heading": 0.0}, host.sid))
    assert wait_for(lambda: host.s.poll(200), 3)
    m = msgpack.unpackb(host.s.recv(), raw=False)
    while m["type"] != "reply":
        m = msgpack.unpackb(host.s.recv(), raw=False)
    assert m["error"]["code"] == "E_FIELD" and "finite" in m["error"]["message"]

"""Bad input gets an error reply with a stable code and the core goes on serving everyone."""
from __future__ import annotations

import random

import msgpack
import pytest
import zmq

from conftest import wait_robots
from robo_comp import protocol as P
from robo_comp.protocol.curve import secure_plain_client


class Raw:
    """A raw DEALER socket speaking (or failing to speak) the protocol."""

    def __init__(self, url: str, token: str) -> None:
        self.s = zmq.Context.instance().socket(zmq.DEALER)
        self.s.setsockopt(zmq.LINGER, 0)
        secure_plain_client(self.s, token)  # the core lets in no connection without a token
        self.s.connect(url)

    #: What the core sends a robot host's connection unasked (the protocol's table: a registered
    #: host gets the team's map deltas, heartbeats, holds...): not the answer to a request.
    PUSHES = frozenset(P.CORE_TO_HOST)

    def ask(self, *frames: bytes, timeout: float = 3.0) -> dict:
        self.s.send_multipart(list(frames))
        while True:
            assert self.s.poll(timeout * 1000), "no reply from the core"
            msg = msgpack.unpackb(self.s.recv(), raw=False)
            if not (isinstance(msg, dict) and msg.get("type") in self.PUSHES):
                return msg

    def close(self) -> None:
        self.s.close(0)


@pytest.fixture
def raw(core):
    import json
    url = json.loads((core.state / "core.json").read_text())["router"]
    r = Raw(url, core.token("red"))
    yield r
    r.close()


def _err(reply: dict) -> str:
    assert reply["type"] == "reply" and reply["ok"] is False, reply
    assert isinstance(reply["error"]["message"], str) and len(reply["error"]["message"]) > 10
    return reply["error"]["code"]


CASES = [
    # (not os.urandom: 4 % of random 64-byte frames start like a large map or list, which is E_TOO_LARGE)
    ("random bytes", [b"\xc1" + random.Random(64).randbytes(63)], "E_MALFORMED"),  # 0xc1: no msgpack type
    ("empty frame", [b""], "E_MALFORMED"),
    ("not a map", [msgpack.packb([1, 2, 3])], "E_MALFORMED"),
    ("two frames", [P.request("robots", 1), b"extra"], "E_MALFORMED"),
    ("no version", [msgpack.packb({"type": "robots", "id": 1})], "E_VERSION"),
    ("future version", [msgpack.packb({"v": 99, "type": "robots", "id": 1})], "E_VERSION"),
    ("unknown type", [P.request("fly", 1)], "E_UNKNOWN_TYPE"),
    ("string id", [msgpack.packb({"v": 2, "type": "robots", "id": "x"})], "E_MALFORMED"),
    ("body not a map", [msgpack.packb({"v": 2, "type": "give", "id": 1, "body": [1]})], "E_FIELD"),
    ("missing field", [P.request("hello", 1, {})], "E_FIELD"),
    ("wrong field type", [P.request("hello", 1, {"token": 5})], "E_FIELD"),
    ("bool as int", [P.request("monitor", 1, {"tag": True})], "E_FIELD"),
    ("huge frame", [P.request("hello", 1, {"token": "x" * (P.MAX_FRAME + 100)})], "E_TOO_LARGE"),
    ("slow to decode", [P.request("radio", 1, {"tag": 1, "data": [{}] * 300_000})], "E_TOO_LARGE"),
    ("array too long", [P.request("radio", 1, {"tag": 1, "data": [None] * (P.MAX_FRAME // 2)})], "E_TOO_LARGE"),
    ("no session", [P.request("robots", 1)], "E_AUTH"),
    ("bad token", [P.request("hello", 1, {"token": "nope"})], "E_AUTH"),
    ("integer map keys", [msgpack.packb({1: 2})], "E_MALFORMED"),
    ("deep nesting", [b"\x91" * 5000 + b"\xc0"], "E_TOO_LARGE"),
]


@pytest.mark.parametrize("name,frames,code", CASES, ids=[c[0] for c in CASES])
def test_bad_frames_get_error_codes(core, raw, name, frames, code):
    assert _err(raw.ask(*frames)) == code


def test_core_keeps_serving_others_under_garbage(core, raw):
    core.robots("red", 2)
    red = core.client("red")
    wait_robots(red, 2)
    rng = random.Random(1)
    for i in range(300):
        n = rng.randrange(1, 200)
        raw.s.send(bytes(rng.randrange(256) for _ in range(n)))
        if i % 50 == 0:
            assert len(red.robots()) == 2  # other clients keep being served
    replies = 0
    while raw.s.poll(1000):
        raw.s.recv()
        replies += 1
        if replies == 300:
            break
    assert replies == 300  # every bad frame got an answer
    assert len(red.robots()) == 2
    assert core.proc.poll() is None


def test_oversized_beyond_socket_cap_only_drops_that_peer(core, raw):
    red = core.client("red")
    raw.s.send(b"\x00" * (P.SOCKET_MAX_FRAME + 10))  # libzmq disconnects this peer
    assert red.robots() == []
    assert core.proc.poll() is None


def test_wrong_types_on_robot_messages(core):
    import json
    tok = core.host_token("red")
    raw = Raw(json.loads((core.state / "core.json").read_text())["router"], tok)  # a robot host's connection
    ok = raw.ask(P.request("register", 1, {"token": tok, "robot_id": "r1", "tasks": [{"name": 3}]}))
    assert _err(ok) == "E_FIELD"
    ok = raw.ask(P.request("register", 2, {"token": tok, "robot_id": "r1", "tasks": []}))
    assert ok["ok"] and ok["body"]["tag"] >= 101
    tag = ok["body"]["tag"]
    sid = ok["body"]["session"]  # every later message of this connection carries it
    # a report for someone else's tag, or with bad fields
    assert _err(raw.ask(P.request("report", 3, {"tag": tag + 50, "x": 1, "y": 1, "heading": 0}, sid))) == "E_NOT_YOURS"
    assert _err(raw.ask(P.request("report", 4, {"tag": tag, "x": "1", "y": 1, "heading": 0}, sid))) == "E_FIELD"
    assert _err(raw.ask(P.request("task.done", 5, {"tag": tag, "task_id": 77, "ok": True, "status": ""}, sid))) == "E_FIELD"
    # the referee's or a team's token never registers robots (only the organiser's host tokens)
    assert _err(raw.ask(P.request("register", 6, {"token": core.token("referee"), "robot_id": "x"}, sid))) == "E_FORBIDDEN"
    assert _err(raw.ask(P.request("register", 9, {"token": core.token("red"), "robot_id": "x"}, sid))) == "E_FORBIDDEN"
    # blue's host token on red's host connection: refused (a connection speaks for one principal)
    assert _err(raw.ask(P.request("register", 8, {"token": core.host_token("blue"), "robot_id": "x"}, sid))) == "E_AUTH"
    # without the secret, the same report is refused whatever it says
    assert _err(raw.ask(P.request("report", 7, {"tag": tag, "x": 1, "y": 1, "heading": 0}))) == "E_AUTH"

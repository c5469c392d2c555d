"""The hostile-client suite: a real core process attacked below the friendly client.

Every attack speaks raw pyzmq frames (forged routing ids, missing and stolen session secrets,
another team's tags, host messages from consoles and the reverse, floods, oversized and nested
frames), plain and under CurveZMQ. Each must be refused with a code, or never reach the core at
all, and leave the attacked session working. ``docs/security.md`` names the defence each test checks.
"""
from __future__ import annotations

import json
import os
import stat
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import msgpack
import pytest
import zmq

from conftest import CoreHandle, wait_for, wait_robots
from robo_comp import protocol as P
from robo_comp.protocol.curve import ClientKeys, load_public, load_secret, secure_client, secure_plain_client
from robo_comp.launch import start_core

#: libzmq's first made-up routing ids when nothing seeds C's rand(): 0x00 + 0x6b8b4567, +1, ...
UNSEEDED_FIRST = 0x6B8B4567


class Peer:
    """A raw DEALER on the core: explicit routing id (or none), hand-made frames, and the session
    secret learnt from a hello/register reply (used only when asked to)."""

    def __init__(self, url: str, routing_id: bytes | None = None, keys: ClientKeys | None = None,
                 token: str | None = None) -> None:
        self.ctx = zmq.Context.instance()
        self.sock = self.ctx.socket(zmq.DEALER)
        self.sock.setsockopt(zmq.LINGER, 0)
        if routing_id is not None:
            self.sock.setsockopt(zmq.ROUTING_ID, routing_id)
        secure_client(self.sock, keys)
        if keys is None:  # the transport's credential: without one the core lets nothing in
            secure_plain_client(self.sock, token)
        self.sock.connect(url)
        self.session: str | None = None
        self.n = 0
        self.pushed: list[dict[str, Any]] = []  # what the core sent that was not a reply

    def send(self, type_: str, body: dict[str, Any] | None = None, *, secret: str | None = None,
             id_: int | None = None) -> int:
        """Send one request with ``secret`` (none by default); return its request id."""
        if id_ is None:
            self.n += 1
            id_ = self.n
        self.sock.send(P.request(type_, id_, body or {}, secret))
        return id_

    def ask(self, type_: str, body: dict[str, Any] | None = None, *, secret: str | None = None,
            timeout: float = 3.0) -> dict[str, Any] | None:
        """Send a request and return its reply (None when nothing answers within ``timeout``)."""
        rid = self.send(type_, body, secret=secret)
        return self.reply(rid, timeout)

    def own(self, type_: str, body: dict[str, Any] | None = None, timeout: float = 3.0) -> dict[str, Any]:
        """A request in this peer's own session (its secret attached); the reply must come."""
        reply = self.ask(type_, body, secret=self.session, timeout=timeout)
        assert reply is not None, f"no reply to {type_}"
        if reply.get("ok") and "session" in (reply.get("body") or {}):
            self.session = reply["body"]["session"]
        return reply

    def reply(self, rid: int, timeout: float = 3.0) -> dict[str, Any] | None:
        """The reply to request ``rid``; pushes read meanwhile are kept in :attr:`pushed`."""
        t_end = time.monotonic() + timeout
        while (left := t_end - time.monotonic()) > 0 and self.sock.poll(left * 1000):
            m = P.unpack(self.sock.recv())
            if m.get("type") == "reply" and m.get("id") == rid:
                return m
            if m.get("type") != "reply":
                self.pushed.append(m)
        return None

    def listen(self, seconds: float) -> list[dict[str, Any]]:
        """Everything the core sends this connection for ``seconds``."""
        got = []
        t_end = time.monotonic() + seconds
        while (left := t_end - time.monotonic()) > 0:
            if self.sock.poll(left * 1000):
                got.append(P.unpack(self.sock.recv()))
        return got

    def close(self) -> None:
        self.sock.close(0)


def code(reply: dict[str, Any] | None) -> str:
    """The error code of a refusal (the test fails on an ok or a missing reply)."""
    assert reply is not None, "no reply: every refusal carries a code"
    assert reply["type"] == "reply" and reply["ok"] is False, reply
    assert len(reply["error"]["message"]) > 20, reply  # a sentence, not a bare code
    return reply["error"]["code"]


def router(core: CoreHandle) -> str:
    return json.loads((core.state / "core.json").read_text())["router"]


def blue_robot(core: CoreHandle) -> tuple[Any, dict[str, Any]]:
    """A real blue robot host process with one robot; returns blue's client and the robot's row."""
    core.robots("blue", 1)
    blue = core.client("blue")
    return blue, wait_robots(blue, 1)[0]


def raw_host(core: CoreHandle, team: str, robot_id: str, routing_id: bytes | None = None) -> tuple[Peer, int]:
    """A raw robot host that said hello and registered one robot: (peer, tag)."""
    host = Peer(router(core), routing_id or P.new_routing_id(), token=core.host_token(team))
    assert host.own("hello", {"token": core.host_token(team), "client": "robots"})["ok"]
    reg = host.own("register", {"token": core.host_token(team), "robot_id": robot_id, "x": 2, "y": 2, "tasks": [
        {"name": "goTo", "args": [{"name": "x", "type": "int"}, {"name": "y", "type": "int"}]}]})
    assert reg["ok"], reg
    return host, reg["body"]["tag"]


# ------------------------------------------------------------------------------- routing ids
def test_made_up_routing_ids_cannot_be_claimed_ahead_or_crash_the_core(core: CoreHandle) -> None:
    """Defence: the core seeds libzmq's routing-id counter at random. Unseeded, every core hands
    connections that set no id the same ids (0x006b8b4567, ...); an attacker who takes the next
    one first makes libzmq abort the core when it hands that id out."""
    url = router(core)
    claims = [Peer(url, b"\x00" + (UNSEEDED_FIRST + k).to_bytes(4, "big"), token=core.token("red"))
              for k in range(16)]
    for p in claims:  # connected with the ids the next connections would get: no session for them
        assert code(p.ask("robots")) == "E_AUTH"
    victims = [Peer(url, token=core.token("blue")) for _ in range(16)]  # no routing id of their own: libzmq makes one up
    for v in victims:
        assert v.own("hello", {"token": core.token("blue")})["ok"]
        assert v.own("robots")["ok"]
    assert core.proc.poll() is None, core.log_tail()
    for p in claims + victims:
        p.close()


def test_short_chosen_routing_ids_are_refused(core: CoreHandle) -> None:
    """Defence: a session opens only on a routing id that cannot be guessed."""
    p = Peer(router(core), b"blue-host", token=core.token("blue"))
    reply = p.ask("hello", {"token": core.token("blue")})
    assert code(reply) == "E_AUTH" and "routing id" in reply["error"]["message"]
    p.close()


def test_a_live_connections_routing_id_cannot_be_taken_over(core: CoreHandle) -> None:
    """Defence: no ROUTER_HANDOVER. A second connection presenting the routing id of blue's host
    is never attached: it gets nothing (no task, no upload source, no event), and blue's host and
    console go on undisturbed."""
    blue = core.client("blue")
    host_id = P.new_routing_id()
    host, tag = raw_host(core, "blue", "b-raw", host_id)
    thief = Peer(router(core), host_id, token=core.token("red"))
    thief.send("hello", {"token": core.token("red")})
    thief.send("give", {"tag": tag, "task": "goTo", "args": [3, 3]})
    # blue uploads code for its robot: the core forwards the source to the robot's host
    rid = blue.ask("upload", tags=[tag], filename="secret_plan.py", source="SECRET = 42\n")
    upload = wait_for(lambda: next((m for m in host.listen(0.2) if m["type"] == "upload"), None), 5.0,
                      "the upload at blue's host")
    assert upload["body"]["source"] == "SECRET = 42\n"  # the real host got it
    host.sock.send(P.ok_reply(upload["id"], {"results": [{"tag": tag, "ok": True, "name": "secret_plan",
                                                          "version": "1", "tasks": []}]}, host.session))
    wait_for(lambda: blue.answer(rid), 5.0, "the upload's answer")
    assert blue.give(tag, "goTo", [3, 3])["task_id"] >= 1
    assert thief.listen(1.0) == []  # nothing at all reached the second connection
    assert host.own("task.next", {"tag": tag})["ok"]  # the real host's session still works
    assert [r["tag"] for r in blue.robots()] == [tag]
    host.close()
    thief.close()


def test_a_vanished_connections_routing_id_gets_nothing(core: CoreHandle) -> None:
    """Defence: ROUTER_MANDATORY + unproven routes. When blue's console disconnects, whoever
    connects next with its routing id gets none of blue's events, and no message of it is served
    without blue's session secret."""
    _, row = blue_robot(core)
    console_id = P.new_routing_id()
    console = Peer(router(core), console_id, token=core.token("blue"))
    assert console.own("hello", {"token": core.token("blue")})["ok"]
    assert console.own("watch", {"on": True})["ok"]
    stolen_from_nowhere = P.new_session_secret()
    console.close()
    time.sleep(1.0)  # heartbeats to the watcher now find no connection: its route is unproven
    thief = Peer(router(core), console_id, token=core.token("red"))
    ref = core.referee()
    for x in (3, 4, 5):
        ref.give(row["tag"], "goTo", [x, 3])
        time.sleep(0.1)
    assert not [m for m in thief.listen(1.0) if m["type"] == "event"]
    assert code(thief.ask("robots")) == "E_AUTH"
    assert code(thief.ask("robots", secret=stolen_from_nowhere)) == "E_AUTH"
    assert code(thief.ask("hello", {"token": core.token("red")})) == "E_AUTH"
    assert not [m for m in thief.listen(0.5) if m["type"] == "event"]
    thief.close()


# ------------------------------------------------------------------------------- sessions
SAMPLE_BODIES: dict[str, dict[str, Any]] = {
    "monitor": {"tag": 101}, "tasks": {"tag": 101}, "give": {"tag": 101, "task": "goTo", "args": [1, 1]},
    "stop": {"tag": 101}, "match": {"action": "start"}, "penalty": {"team": "red", "points": 5, "reason": "x"},
    "broadcast": {"message": "hi"}, "find": {"tag": 101, "x": 1, "y": 1}, "picture.get": {"id": 1},
    "map.delta": {"since": 0}, "upload": {"tags": [101], "filename": "a.py", "source": "x = 1\n"},
    "unload": {"tags": [101], "name": "a"}, "extensions": {"tag": 101}, "approve": {"upload_id": 1},
    "report": {"tag": 101, "x": 1, "y": 1, "heading": 0}, "reports": {"tags": [101], "x": [1], "y": [1],
                                                                        "heading": [0]},
    "task.next": {"tag": 101}, "task.done": {"tag": 101, "task_id": 1, "ok": True, "status": "done"},
    "radio": {"tag": 101, "data": "hi"}, "leave": {"tag": 101},
    "picture": {"tag": 101, "x": 1, "y": 1, "heading": 0, "png": b"\x89PNG"},
    "bump": {"tag": 101, "x": 1, "y": 1}, "advertise": {"tag": 101, "tasks": []},
    "log": {"stream": "out", "text": "hi"},
}


#: A well-typed value for each field kind of the message table.
KIND_SAMPLES: dict[str, Any] = {"int": 101, "number": 1.0, "str": "x", "bool": True, "list": [101], "map": {},
                                "bytes": b"x", "any": "x", "int or nil": None}


def sample_body(type_: str) -> dict[str, Any]:
    """A body every field of which has the right type (the table's, or a hand-made sample)."""
    if type_ in SAMPLE_BODIES:
        return SAMPLE_BODIES[type_]
    return {name: KIND_SAMPLES[kind] for name, (kind, _required) in P.REQUESTS[type_].items()}


def test_nothing_but_hello_is_served_before_hello(core: CoreHandle) -> None:
    """Defence: every message needs a proved session (E_AUTH), whatever secret it makes up."""
    p = Peer(router(core), P.new_routing_id(), token=core.token("red"))
    for type_ in sorted(set(P.REQUESTS) - {"hello", "register", "bye"}):
        body = sample_body(type_)
        assert code(p.ask(type_, body)) == "E_AUTH", type_
        assert code(p.ask(type_, body, secret=P.new_session_secret())) == "E_AUTH", type_
    assert core.referee().request("stats")["robots"] == {}
    p.close()


def test_a_secret_works_only_on_its_own_connection(core: CoreHandle) -> None:
    """Defence: a session is the pair (connection, secret): a secret replayed from another
    connection, with or without a session there, proves nothing; a forged one neither."""
    host, tag = raw_host(core, "red", "r-raw")
    stolen = host.session
    assert stolen is not None and len(stolen) == 2 * P.SESSION_BYTES
    frame = P.request("give", 9, {"tag": tag, "task": "goTo", "args": [4, 4]}, stolen)
    replay = Peer(router(core), P.new_routing_id(), token=core.token("red"))  # even with red's credential
    replay.sock.send(frame)  # the very bytes red's connection would send
    assert code(replay.reply(9)) == "E_AUTH"
    blue = Peer(router(core), P.new_routing_id(), token=core.token("blue"))
    assert blue.own("hello", {"token": core.token("blue")})["ok"]
    assert code(blue.ask("give", {"tag": tag, "task": "goTo", "args": [4, 4]}, secret=stolen)) == "E_AUTH"
    forged = stolen[:-1] + ("0" if stolen[-1] != "0" else "1")
    assert code(host.ask("task.next", {"tag": tag}, secret=forged)) == "E_AUTH"
    assert code(host.ask("task.next", {"tag": tag}, secret=stolen.upper())) == "E_AUTH"
    assert code(host.ask("task.next", {"tag": tag}, secret="ü" * 32)) == "E_AUTH"
    assert code(host.ask("task.next", {"tag": tag})) == "E_AUTH"  # none at all
    assert host.own("task.next", {"tag": tag})["ok"]  # the real session is still served
    tasks = core.referee().tasks(tag)
    assert tasks["current"] is None and tasks["done"] == []  # no give got through
    for p in (host, replay, blue):
        p.close()


def test_forged_request_ids_cannot_answer_for_another_host(core: CoreHandle) -> None:
    """Defence: the core takes an answer to its own request (stop, upload) only from the host
    of the robot it asked; another team's host that guesses the request ids changes nothing."""
    blue, row = blue_robot(core)
    red_host, _ = raw_host(core, "red", "r-raw")
    rid = blue.ask("upload", tags=[row["tag"]], filename="plan.py", source="def robo_comp_init(api):\n    pass\n")
    for cid in range(1, 200):  # the core numbers its requests to hosts 1, 2, 3, ...
        red_host.sock.send(P.ok_reply(cid, {"results": [{"tag": row["tag"], "ok": False, "message": "forged"}]},
                                      red_host.session))
    answer = wait_for(lambda: _answer_or_error(blue, rid), 10.0, "the upload's answer")
    assert "forged" not in json.dumps(answer)
    assert blue.stop(row["tag"])["tag"] == row["tag"]  # the real host confirms the stop
    red_host.close()


def _answer_or_error(client: Any, rid: int) -> Any:
    try:
        return client.answer(rid)
    except Exception as e:  # an upload refusal is an answer too
        return {"error": str(e)}


def test_another_teams_tag_in_every_message_kind(core: CoreHandle) -> None:
    """Defence: ownership on every command. Red's console and red's host name blue's robot in
    every message kind that names a robot: each is refused with a code, blue's robot unmoved."""
    blue, row = blue_robot(core)
    tag = row["tag"]
    before = core.referee().monitor(tag)
    console = Peer(router(core), P.new_routing_id(), token=core.token("red"))
    assert console.own("hello", {"token": core.token("red")})["ok"]
    host, own_tag = raw_host(core, "red", "r-raw")
    as_console = {
        "monitor": {"tag": tag}, "tasks": {"tag": tag}, "give": {"tag": tag, "task": "goTo", "args": [5, 5]},
        "stop": {"tag": tag}, "upload": {"tags": [tag], "filename": "a.py", "source": "x = 1\n"},
        "unload": {"tags": [tag], "name": "a"}, "extensions": {"tag": tag}, "map": {"tag": tag},
        "find": {"tag": tag, "x": 1, "y": 1}, "disqualify": {"tag": tag},
    }
    as_host = {
        "report": {"tag": tag, "x": 9, "y": 9, "heading": 0},
        "reports": {"tags": [tag], "x": [9], "y": [9], "heading": [0]},
        "task.next": {"tag": tag}, "task.done": {"tag": tag, "task_id": 1, "ok": True, "status": "done"},
        "radio": {"tag": tag, "data": "hi"}, "leave": {"tag": tag},
        "picture": {"tag": tag, "x": 1, "y": 1, "heading": 0, "png": b"\x89PNG"},
        "bump": {"tag": tag, "x": 1, "y": 1}, "advertise": {"tag": tag, "tasks": []},
        "log": {"tag": tag, "stream": "out", "text": "blue's robot says hi"},
        "register": {"token": core.token("blue"), "robot_id": row["robot_id"]},  # blue's robot, blue's token
    }
    for type_, body in as_console.items():
        assert code(console.ask(type_, body, secret=console.session)) in ("E_NOT_YOURS", "E_FORBIDDEN"), type_
    for type_, body in as_host.items():
        assert code(host.ask(type_, body, secret=host.session)) in ("E_NOT_YOURS", "E_AUTH", "E_FORBIDDEN"), type_
    assert code(host.ask("radio", {"tag": own_tag, "to": tag, "data": "hi"}, secret=host.session)) == "E_NOT_YOURS"
    after = core.referee().monitor(tag)
    assert (after["status"], after["team"]) == (before["status"], before["team"]) == ("connected", "blue")
    assert (after["x"], after["y"]) != (9, 9)  # red's forged report did not move it
    assert core.referee().tasks(tag)["done"] == []
    assert blue.give(tag, "goTo", [3, 3])["task_id"] >= 1  # blue's own command still works
    console.close()
    host.close()


def test_host_messages_from_a_console_and_console_messages_from_a_host(core: CoreHandle) -> None:
    """Defence: a robot's messages come only from the connection that registered it; referee
    powers need the referee's token. Red's console speaks for red's hosted robot, red's host
    for the referee: refused, and red's robot keeps reporting."""
    host, tag = raw_host(core, "red", "r-raw")
    console = Peer(router(core), P.new_routing_id(), token=core.token("red"))
    assert console.own("hello", {"token": core.token("red")})["ok"]
    for type_ in ("report", "task.next", "task.done", "leave", "picture", "bump", "advertise"):
        body = dict(SAMPLE_BODIES[type_], tag=tag)
        assert code(console.ask(type_, body, secret=console.session)) == "E_FORBIDDEN", type_
    for type_ in ("stats", "match", "penalty", "approve", "broadcast", "disqualify"):
        body = SAMPLE_BODIES.get(type_, {"team": "blue"} if type_ == "disqualify" else {})
        assert code(host.ask(type_, body, secret=host.session)) == "E_FORBIDDEN", type_
    host.send("report", {"tag": tag, "x": 3.5, "y": 2.5, "heading": 0}, secret=host.session)
    wait_for(lambda: core.referee().monitor(tag)["x"] == 3.5, 3.0, "the host's own report")
    assert core.referee().monitor(tag)["status"] == "connected"
    console.close()
    host.close()


def test_a_flood_of_bad_hellos_is_refused_and_logged_in_bulk(core: CoreHandle) -> None:
    """Defence: a bad hello changes nothing; refusals without a session are logged once a beat
    with their count, so a flood neither stops the core nor floods its log or the referee."""
    blue = core.client("blue")
    # a credential at the transport (blue's: a teammate), then hellos with tokens made up
    flood = [Peer(router(core), P.new_routing_id(), token=core.token("blue")) for _ in range(20)]
    for i in range(100):
        for p in flood:
            p.send("hello", {"token": f"guess-{i}-{os.urandom(8).hex()}"})
        if i % 25 == 0:
            assert blue.robots() == []  # the real session is served throughout
    refused = 0
    for p in flood:
        for _ in range(100):
            assert p.sock.poll(10_000), "every bad hello is answered"
            assert P.unpack(p.sock.recv())["error"]["code"] == "E_AUTH"
            refused += 1
    assert refused == 2000
    assert blue.robots() == []

    def logged() -> list[dict[str, Any]] | None:
        rows = [e for e in core.logged_events("refused") if e["data"].get("type") == "hello"]
        return rows if sum(e["data"]["count"] for e in rows) == 2000 else None

    rows = wait_for(logged, 5.0, "the refusals in the log")
    assert len(rows) < 100  # counted per beat, not one record each
    assert {e["data"]["code"] for e in rows} == {"E_AUTH"} and {e["team"] for e in rows} == {None}
    for p in flood:
        p.close()


def test_oversized_and_deeply_nested_frames_leave_the_session_working(core: CoreHandle) -> None:
    """Defence: frame limits (E_TOO_LARGE over 1 MiB; libzmq drops a peer over
    SOCKET_MAX_FRAME) and a decoder that refuses deep nesting (E_TOO_LARGE), before any handler runs."""
    host, tag = raw_host(core, "red", "r-raw")
    big = P.request("report", 7, {"tag": tag, "x": 1, "y": 1, "heading": 0,
                                  "sensors": {"x": "y" * (P.MAX_FRAME + 100)}}, host.session)
    host.sock.send(big)
    assert code(host.reply(0)) == "E_TOO_LARGE"  # refused before its id is read
    head = msgpack.packb({"v": 2, "type": "report", "id": 8, "s": host.session})  # a map of 4 ...
    nested = b"\x85" + head[1:] + msgpack.packb("body") + b"\x91" * 3000 + b"\xc0"  # ... made 5: a deep body
    host.sock.send(nested)
    assert code(host.reply(0)) == "E_TOO_LARGE"
    host.sock.send(b"\x91" * 100_000 + b"\xc0")
    assert code(host.reply(0)) == "E_TOO_LARGE"
    assert host.own("task.next", {"tag": tag})["ok"]  # the session survived all three
    huge = Peer(router(core), P.new_routing_id(), token=core.token("red"))
    huge.sock.send(b"\x00" * (P.SOCKET_MAX_FRAME + 10))  # libzmq cuts this peer off
    assert host.own("task.next", {"tag": tag})["ok"]
    assert core.proc.poll() is None
    host.close()
    huge.close()


def test_an_old_client_gets_a_clear_error_not_silence(core: CoreHandle) -> None:
    """Protocol 1 (no session secret) is answered with E_VERSION and what to do."""
    p = Peer(router(core), P.new_routing_id(), token=core.token("red"))
    p.sock.send(msgpack.packb({"v": 1, "type": "hello", "id": 1, "body": {"token": core.token("red")}}))
    reply = p.reply(1)
    assert code(reply) == "E_VERSION"
    assert "version 1" in reply["error"]["message"] and "update robo_comp" in reply["error"]["message"]
    p.close()


def test_uploaded_sources_and_the_event_log_are_private(core: CoreHandle) -> None:
    """Defence: a team's code on the core's disk is 0600 in 0700 folders, like the tokens."""
    core.robots("red", 1)
    red = core.client("red")
    tag = wait_robots(red, 1)[0]["tag"]
    source = (Path(__file__).parents[1] / "team_templates" / "extensions" / "square.py").read_text()
    assert red.upload([tag], "square.py", source)["ok"]
    folder = core.state / "uploads"
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700
    assert stat.S_IMODE((folder / "red").stat().st_mode) == 0o700
    files = list((folder / "red").iterdir())
    assert files and all(stat.S_IMODE(f.stat().st_mode) == 0o600 for f in files)
    assert stat.S_IMODE((core.state / "events.log").stat().st_mode) == 0o600


# ------------------------------------------------------------------------------- CurveZMQ
@pytest.fixture
def curve_core(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Any:
    """A ``--curve`` core with teams red and blue, keys made by ``robo-comp keys``."""
    monkeypatch.delenv("ROBO_COMP_CURVE_CERT", raising=False)
    monkeypatch.delenv("ROBO_COMP_CORE_KEY", raising=False)
    state = tmp_path / "state"
    out = subprocess.run([sys.executable, "-m", "robo_comp.cli", "keys", "--state", str(state),
                          "--teams", "red,blue"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    h = CoreHandle(state, None, start_core(state, "--heartbeat", "0.2", "--teams", "red,blue", "--curve"))
    yield h
    h.close()


def _keys(state: Path, owner: str) -> ClientKeys:
    public, secret = load_secret(state / "keys" / f"{owner}.key_secret")
    return ClientKeys(public, secret, load_public(state / "keys" / "core.key"))


def test_curve_routing_id_reuse_with_another_teams_key(curve_core: CoreHandle) -> None:
    """Defence: under CURVE every frame's key must be the key its session was opened with. Red,
    with its own valid key, presents blue's routing id: ignored while blue is connected; after
    blue is gone, even blue's session secret does not let red's key in, and red gets no push."""
    url, state = router(curve_core), curve_core.state
    blue_id = P.new_routing_id()
    blue = Peer(url, blue_id, _keys(state, "blue"))
    assert blue.own("hello", {"token": curve_core.token("blue")})["ok"]
    assert blue.own("watch", {"on": True})["ok"]
    secret = blue.session
    red = Peer(url, blue_id, _keys(state, "red"))
    red.send("hello", {"token": curve_core.token("red")})
    red.send("robots", secret=secret)
    assert red.listen(1.0) == []  # never attached: blue's connection holds the id
    assert blue.own("robots")["ok"]
    blue.close()
    red.close()
    time.sleep(1.0)  # heartbeats to blue's route fail: unproven
    red = Peer(url, blue_id, _keys(state, "red"))
    reply = red.ask("robots", secret=secret)  # as if red had blue's secret
    assert code(reply) == "E_AUTH" and "blue's CurveZMQ key" in reply["error"]["message"]
    assert not [m for m in red.listen(0.8) if m["type"] == "event"]
    again = Peer(url, P.new_routing_id(), _keys(state, "blue"))  # blue comes back on a new connection
    assert again.own("hello", {"token": curve_core.token("blue")})["ok"]
    assert again.own("robots")["ok"]
    red.close()
    again.close()

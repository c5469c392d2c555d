"""The transport under attack: a real core process, attacked with raw TCP (hand-made ZMTP) and raw
pyzmq, below every friendly client.

- A peer without a credential sends the parts of one multipart message and never the last: the
  core buffers nothing of it (its memory stays within 50 MiB of where it was).
- A peer *with* a valid token does the same: the core cuts the connection once it holds more than
  one whole frame of a message it does not finish (its peak memory stays within 50 MiB), and cuts
  the biggest holders when connections together hold more than 16 MiB; whole frames, even sent
  slowly, are not cut.
- Such a peer gets no reply to anything; its refused handshakes are logged in bulk.
- Frames that msgpack would be slow to decode are refused before decoding gets far.
- A client that says hello again (same principal, same ``instance``) ends its old session.

``docs/security.md`` names the defence each test checks; ``bench/bench_transport.py`` measures
the figures (memory under the attack, longest loop turn under slow frames).
"""
from __future__ import annotations

import contextlib
import json
import resource
import socket
import struct
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import zmq
from zmq.auth.thread import ThreadAuthenticator

from conftest import CoreHandle, wait_for, wait_robots
from test_hostile_clients import Peer, code, router
from robo_comp import protocol as P
from robo_comp.core.guard import HOLD_MAX, HOLD_TOTAL, HOLD_UNFINISHED, ConnectionGuard, GuardLimits, _the_kernel
from robo_comp.testing.zmtp import (
    core_peak, core_rss, reset_core_peak, router_address, zmtp_command, zmtp_expect, zmtp_frame, zmtp_greeting,
    zmtp_initiate, zmtp_null_handshake, zmtp_open, zmtp_plain_handshake,
)

MiB = 1 << 20


def peer(core: CoreHandle, token: str | None) -> Peer:
    """A raw DEALER on ``core`` presenting ``token`` to the transport (None: no credential)."""
    return Peer(router(core), P.new_routing_id(), token=token)


def _send(p: Peer, frame: bytes) -> None:
    """Send without ever blocking: a socket the core refused may have no connection to queue on."""
    with contextlib.suppress(zmq.Again):
        p.sock.send(frame, zmq.NOBLOCK)


def _raw_connect(core: CoreHandle) -> socket.socket:
    s = socket.create_connection(router_address(core.state), timeout=5.0)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1 << 20)
    return s


def _push_unfinished(s: socket.socket, total: int, part: int = 8 * MiB) -> int:
    """Send parts of one multipart message (MORE set on every one) up to ``total`` bytes, or until
    the core closes the connection; return the bytes the core accepted. Each part starts with 1
    (a subscription, to a PUB socket: libzmq itself drops a peer whose short parts start with 0)."""
    chunk = zmtp_frame(b"\x01" + b"\0" * (part - 1), more=True) * max(1, MiB // part)
    sent = 0
    try:
        while sent < total:
            s.sendall(chunk)
            sent += len(chunk)
    except OSError:  # the core closed the connection: what it took is what we sent so far
        pass
    return sent


# ------------------------------------------------------------------ nothing buffered without a credential
@pytest.mark.parametrize("mechanism", ["NULL", "PLAIN"])
def test_unfinished_multipart_from_a_peer_without_a_credential_holds_no_memory(
        core: CoreHandle, mechanism: str) -> None:
    """Defence: PLAIN handshake with the token as password, checked by the core's ZAP handler
    (and ZMQ_MAXMSGSIZE on the ROUTER). A raw peer greets with NULL (no credential) or PLAIN with
    a made-up token, then sends 8 MiB parts of one message with MORE set, 256 MiB in all: the
    core's memory stays within 50 MiB of its baseline, and it goes on serving."""
    blue = core.client("blue")
    assert blue.robots() == []
    baseline = core_rss(core.state)
    s = _raw_connect(core)
    s.sendall(zmtp_greeting(mechanism))
    if mechanism == "NULL":
        s.sendall(zmtp_command(b"READY", {b"Socket-Type": b"DEALER"}))
    else:
        s.sendall(zmtp_command(b"HELLO", body=b"\x09robo_comp" + b"\x10" + b"not-a-real-token"))
    _push_unfinished(s, 256 * MiB)
    time.sleep(0.5)  # let the core's I/O thread take in whatever reached it
    grown = core_rss(core.state) - baseline
    s.close()
    assert grown < 50 * MiB, f"the core grew by {grown / MiB:.0f} MiB for a peer without a credential"
    assert blue.robots() == []  # still serving


def test_an_unfinished_message_to_the_public_feed_holds_no_memory(core: CoreHandle) -> None:
    """Defence: the PUB socket's subscribers need no credential (walls, the web), so the core cuts
    a subscriber that sends more than a few subscriptions' worth (64 KiB, read from the kernel's
    TCP_INFO) and ZMQ_MAXMSGSIZE there is 1 KiB. A raw peer that greets the public feed as a SUB and
    sends 256 MiB as 1 KB parts of one message: the core cuts it (logged), stays within 50 MiB,
    and a real subscriber still gets events."""
    info = json.loads((core.state / "core.json").read_text())
    host, port = info["pub"].removeprefix("tcp://").rsplit(":", 1)
    sub = zmq.Context.instance().socket(zmq.SUB)
    sub.setsockopt(zmq.LINGER, 0)
    sub.setsockopt(zmq.SUBSCRIBE, b"")
    sub.connect(info["pub"])
    baseline = core_rss(core.state)

    def cuts() -> list[dict[str, Any]]:
        return [e for e in core.logged_events("refused") if e["data"].get("type") == "connect"]

    # one handshake, then 256 MiB as 1 KB parts of one message: the core's own look at what the
    # connection sent cuts it, long before libzmq's limits or the 256 MiB are reached
    s = socket.create_connection((host, int(port)), timeout=5.0)
    zmtp_null_handshake(s, b"SUB")
    sent = _push_unfinished(s, 256 * MiB, part=1000)
    time.sleep(0.5)
    grown = core_rss(core.state) - baseline
    s.close()
    assert sent < 256 * MiB, "the core read 256 MiB of one unfinished message from a subscriber"
    assert grown < 50 * MiB, f"the core grew by {grown / MiB:.0f} MiB for a subscriber without a credential"
    wait_for(cuts, 5.0, "the core's cut of the subscriber, in the log")
    assert "subscriber" in cuts()[0]["data"]["message"], core.log_tail()
    ref = core.referee()
    wait_for(lambda: (ref.request("broadcast", message="still here"), sub.poll(200))[1], 10.0,
             "an event on the public feed")
    sub.close(0)


# ------------------------------------------------------------------ what a peer with a token may hold
def _cuts(core: CoreHandle, words: str) -> list[dict[str, Any]]:
    """The core's bulk records of connections it cut for a reason that says ``words``."""
    return [e for e in core.logged_events("refused")
            if e["data"].get("type") == "connect" and words in e["data"]["message"]]


def _was_cut(s: socket.socket) -> bool:
    """Whether the core reset this raw connection (it sends nothing else to a peer that never
    finished a message)."""
    s.setblocking(False)
    try:
        return s.recv(1) == b""
    except BlockingIOError:
        return False
    except OSError:
        return True


@pytest.mark.parametrize("part", [512 << 10, MiB], ids=["512KiB", "1MiB"])
def test_an_unfinished_message_from_a_peer_with_a_token_is_cut(core: CoreHandle, part: int) -> None:
    """Defence: the guard weighs what libzmq read off each connection (the kernel's TCP_INFO less
    FIONREAD) against what the core was handed of it (ZMQ_SRCFD, frames counted as on the wire),
    and cuts a connection that holds more than HOLD_UNFINISHED (one whole frame and 128 KiB) while
    nothing complete waits for the core; it looks every 50 ms and at once when the core's memory
    grew 8 MiB. A raw peer completes PLAIN with red's valid token and sends parts of one message
    under ZMQ_MAXMSGSIZE (MORE on every one), 256 MiB in all: it is cut, the core's peak memory
    stays within 50 MiB of where it was, the cut is logged, and other clients are served. Before,
    all 256 MiB went in and the core grew by as much."""
    blue = core.client("blue")
    assert blue.robots() == []
    baseline = core_rss(core.state)
    reset_core_peak(core.state)
    s = _raw_connect(core)
    zmtp_plain_handshake(s, core.token("red").encode())
    sent = _push_unfinished(s, 256 * MiB, part=part)
    time.sleep(0.5)  # let the core's I/O thread take in whatever reached it
    grown = core_peak(core.state) - baseline
    s.close()
    assert sent < 256 * MiB, "the core never cut a connection holding 256 MiB of one unfinished message"
    assert grown < 50 * MiB, f"the core grew by {grown / MiB:.0f} MiB for one unfinished message"
    # cut as unfinished, as more than HOLD_MAX, or as handed nothing at two looks in a row: on a
    # loaded machine the core's looks may come late or find other clients' messages waiting
    try:
        found = wait_for(lambda: _cuts(core, "held"), 5.0, "the cut in the log")
    except AssertionError:
        raise AssertionError(f"no cut for what a connection held in the log; refusals: {core.logged_events('refused')}; "
                             f"stats: {core.referee().request('stats')}") from None
    assert found[0]["data"]["code"] == "E_RATE" and found[0]["data"]["address"] == "127.0.0.1"
    assert blue.robots() == []  # still serving
    assert core.referee().request("stats")["connections_cut"] == 1


def test_whole_frames_from_a_peer_with_a_token_are_not_cut(core: CoreHandle) -> None:
    """The bound leaves whole messages alone, however large and however slowly they come: a peer
    with red's token sends 24 frames of the largest size libzmq lets through (1 MiB + 64 KiB, each
    refused E_TOO_LARGE) as fast as it can, and a raw one sends such a frame in 64 KiB pieces over
    about a second, so that looks find it unfinished: every one is answered and no connection is
    cut."""
    burst = peer(core, core.token("red"))
    big = b"\x01" * P.SOCKET_MAX_FRAME
    for _ in range(24):
        burst.sock.send(big)
    assert [code(burst.reply(0)) for _ in range(24)] == ["E_TOO_LARGE"] * 24
    s = _raw_connect(core)
    zmtp_plain_handshake(s, core.token("red").encode())
    whole = zmtp_frame(big)
    for k in range(0, len(whole), 64 << 10):
        s.sendall(whole[k:k + (64 << 10)])
        time.sleep(0.06)  # spread over about 18 looks of the guard
    zmtp_expect(s, b"E_TOO_LARGE")  # ConnectionError: the core closed the connection of a peer sending slowly
    s.close()
    assert burst.own("hello", {"token": core.token("red")})["ok"]
    burst.close()
    assert core.referee().request("stats")["connections_cut"] == 0


def test_connections_holding_more_than_the_total_together_are_cut(core: CoreHandle) -> None:
    """Defence: HOLD_TOTAL. 20 raw connections with red's token each hold 1 MiB of an unfinished
    message, under the bound of one connection (HOLD_UNFINISHED) but 20 MiB together, over 16 MiB:
    the biggest holders are cut until the rest hold 16 MiB at most, the others are left, the core
    stays within 50 MiB of where it was, and a console is served."""
    blue = core.client("blue")
    baseline = core_rss(core.state)
    reset_core_peak(core.state)
    socks = []
    for _ in range(20):
        s = _raw_connect(core)
        zmtp_plain_handshake(s, core.token("red").encode())
        socks.append(s)
    assert HOLD_UNFINISHED > MiB + 64 and 20 * MiB > HOLD_TOTAL
    for s in socks:
        s.sendall(zmtp_frame(b"\x01" * (MiB // 2), more=True) * 2)
    wait_for(lambda: _cuts(core, "together"), 5.0, "the cut in the log")
    grown = core_peak(core.state) - baseline
    cut = sum(_was_cut(s) for s in socks)
    for s in socks:
        s.close()
    assert 20 - HOLD_TOTAL // MiB <= cut < 20, f"{cut} of 20 connections cut"
    assert grown < 50 * MiB, f"the core grew by {grown / MiB:.0f} MiB"
    assert blue.robots() == []


def test_a_backlog_the_core_does_not_take_is_cut() -> None:
    """Defence: the same look on complete messages (real ROUTER, real TCP peer, the guard a core
    uses; the core's loop played by this test). A peer with a NULL handshake sends 1 MiB messages
    whole, two a turn of the loop. Taken as they come, 40 MiB of them cut nothing; when the loop
    takes one a turn (a backlog growing while the core takes some), the connection is cut once it
    holds more than HOLD_MAX; when the loop takes none, at the second look that finds it over
    HOLD_UNFINISHED with nothing handed in between. The loop's clock brings a look every turn."""
    ctx = zmq.Context()
    router = ctx.socket(zmq.ROUTER)
    router.setsockopt(zmq.LINGER, 0)
    router.setsockopt(zmq.RCVHWM, 100_000)
    port = router.bind_to_random_port("tcp://127.0.0.1")
    guard = ConnectionGuard.watch(router, port, GuardLimits(64), hold=True)
    message = zmtp_frame(b"\x01" * MiB)
    # the loop's clock moves past the next look at every turn, so the guard looks once a turn
    # however slowly a loaded machine runs the turns (at most 2 MiB more between two looks)
    clock = [time.monotonic()]

    def attack(take: int | None, total: int) -> tuple[int, str]:
        """Send ``total`` bytes of whole messages, two a turn, the loop taking ``take`` a turn (None:
        all) and sweeping; return what was sent and why the guard cut it ('' if it did not)."""
        s = socket.create_connection(("127.0.0.1", port), timeout=5.0)
        zmtp_null_handshake(s)
        sent, cut, t_end = 0, "", time.monotonic() + 30.0
        while not cut and time.monotonic() < t_end:
            if sent < total:
                with contextlib.suppress(OSError):  # cut: the reason comes from the guard
                    s.sendall(message * 2)
                    sent += 2 * len(message)
                if sent >= total:
                    t_end = min(t_end, time.monotonic() + 0.5)  # looks after the last message
            time.sleep(0.002)
            guard.serve()
            for _ in range(100_000 if take is None else take):
                try:
                    first = router.recv(zmq.NOBLOCK, copy=False)
                except zmq.Again:
                    break
                guard.took(first, [first.bytes, *router.recv_multipart()])
            clock[0] += 10.0  # (a look that took up to 0.2 s still leaves the next one due)
            guard.sweep(clock[0])
            if guard.cuts_waiting:
                cut = next(iter(guard.take_cut().values())).reason
        s.close()
        while router.poll(100):  # what is left of it
            router.recv_multipart()
        return sent, cut

    try:
        sent, cut = attack(None, 40 * MiB)
        assert cut == "" and sent >= 40 * MiB
        sent, cut = attack(1, 64 * MiB)  # one taken a turn, two come: a backlog of a MiB more each turn
        assert f"over {HOLD_MAX >> 20} MiB" in cut and sent < 64 * MiB, cut
        sent, cut = attack(0, 64 * MiB)
        assert "at two looks" in cut and sent < 32 * MiB, cut
    finally:
        guard.close()
        router.close(0)
        ctx.term()


def test_a_cut_decided_for_a_closed_connection_spares_the_one_that_got_its_number() -> None:
    """The guard reads a connection's counts in place and cuts it through a duplicate of libzmq's
    descriptor; libzmq's I/O thread may close that connection in between (it broke a limit of its
    own) and give the number to the next connection it accepts: an honest client connecting at
    that moment (CI saw one fail its handshake right after an attack). Real ROUTER, real TCP peers,
    the guard a core uses: peer A is accepted and seen by the guard; A goes away and peer B gets
    A's descriptor before the guard hears of it; the cut the guard decided for A does not touch B,
    which then gets its answer."""
    ctx = zmq.Context()
    router = ctx.socket(zmq.ROUTER)
    router.setsockopt(zmq.LINGER, 0)
    port = router.bind_to_random_port("tcp://127.0.0.1")
    guard = ConnectionGuard.watch(router, port, GuardLimits(64), hold=True)
    try:
        a = socket.create_connection(("127.0.0.1", port), timeout=5.0)
        zmtp_null_handshake(a)
        t_end = time.monotonic() + 10
        while not guard.conns and time.monotonic() < t_end:
            guard.serve()
            time.sleep(0.01)
        [(fd, address)] = guard.conns.items()
        a.close()
        time.sleep(0.3)  # libzmq closes A's descriptor (the guard is not told yet: serve is not called)
        b = socket.create_connection(("127.0.0.1", port), timeout=5.0)
        zmtp_null_handshake(b)
        with guard._peek(fd) as sock:  # noqa: SLF001  (the descriptor number, now B's)
            if sock is None or sock.getpeername()[1] != b.getsockname()[1]:
                pytest.skip("libzmq gave B another descriptor number than A's: no reuse to test")
        guard._cut_fd(fd, address, "a cut decided for A")  # noqa: SLF001  (the guard's own cut, as a sweep makes it)
        assert guard.cut_total == 0, "the guard cut the connection that got a closed one's descriptor"
        b.sendall(zmtp_frame(b"", more=True) + zmtp_frame(b"hello from B"))
        assert router.poll(5000), "B's message never reached the ROUTER"
        ident, _, _body = router.recv_multipart()
        router.send_multipart([ident, b"", b"answer"])
        b.settimeout(5.0)
        zmtp_expect(b, b"answer")  # ConnectionError: B was cut
        b.close()
    finally:
        guard.close()
        router.close(0)
        ctx.term()


@pytest.mark.parametrize("mechanism", ["PLAIN", "CURVE"])
def test_what_the_core_was_handed_is_counted_as_it_crossed_the_wire(mechanism: str) -> None:
    """The count the bound rests on (real ROUTER and DEALER, the guard a core uses, the core's
    receive loop played by this test): after 3,000 messages of 10 to 300 bytes (ZMTP headers short
    and long, on both sides of 255; under CurveZMQ a MESSAGE command around each), what the kernel
    says libzmq read off the connection, less what ``took`` counted, grew by the peer's answers to
    the ROUTER's pings only (7 bytes each, 40 under CurveZMQ): a whole number of them, no more than
    the pings sent. A count one byte too high a frame would let a peer bank room to hold memory
    later; one too low would cut an honest client in the end."""
    SIZES = (10, 222, 223, 255, 256, 300)  # under CurveZMQ 222 and 223 bytes become 255 and 256
    ctx = zmq.Context()
    router, dealer = ctx.socket(zmq.ROUTER), ctx.socket(zmq.DEALER)
    router.setsockopt(zmq.HEARTBEAT_IVL, 50)
    if mechanism == "CURVE":
        server_public, server_secret = zmq.curve_keypair()
        client_public, client_secret = zmq.curve_keypair()
        router.curve_server, router.curve_secretkey = True, server_secret
        dealer.curve_serverkey, dealer.curve_publickey, dealer.curve_secretkey = (server_public, client_public,
                                                                                  client_secret)
    else:  # PLAIN needs a ZAP handler to let anyone in: pyzmq's own, in a thread
        auth = ThreadAuthenticator(ctx)
        auth.start()
        auth.configure_plain(domain="*", passwords={"robo_comp": "a-token"})
        router.plain_server = True
        dealer.plain_username, dealer.plain_password = b"robo_comp", b"a-token"
    port = router.bind_to_random_port("tcp://127.0.0.1")
    guard = ConnectionGuard.watch(router, port, GuardLimits(64), hold=True)
    dealer.connect(f"tcp://127.0.0.1:{port}")
    kernel = _the_kernel()

    def take(n: int) -> int:
        fd = -1
        for _ in range(n):
            assert router.poll(5000)
            first = router.recv(copy=False)
            guard.took(first, [first.bytes, *router.recv_multipart()])
            fd = first.get(zmq.SRCFD)
        return fd

    def unhanded(fd: int) -> int:
        received = kernel.received(fd)
        assert received is not None
        return received - kernel.unread(fd) - guard.handed[fd]

    try:
        dealer.send(b"hello")
        fd = take(1)
        guard.serve()
        t0, before = time.monotonic(), unhanded(fd)  # the handshake and the answers to pings so far
        for k in range(3000):
            dealer.send(b"x" * SIZES[k % len(SIZES)])
            if k % 100 == 99:
                take(100)
                time.sleep(0.01)
        time.sleep(0.3)
        pongs = unhanded(fd) - before
        pings = (time.monotonic() - t0) / 0.05 + 2
        assert pongs % guard.pong_bytes == 0 and 0 <= pongs <= pings * guard.pong_bytes, (pongs, guard.pong_bytes)
        assert guard.pong_bytes == (40 if mechanism == "CURVE" else 7)
    finally:
        guard.close()
        dealer.close(0)
        router.close(0)
        if mechanism == "PLAIN":
            auth.stop()
        ctx.term()


def test_a_huge_handshake_command_is_cut_off(core: CoreHandle) -> None:
    """Defence: ZMQ_MAXMSGSIZE holds during the handshake too: a PLAIN HELLO command of 64 MiB is
    cut off after at most SOCKET_MAX_FRAME bytes."""
    baseline = core_rss(core.state)
    s = _raw_connect(core)
    s.sendall(zmtp_greeting("PLAIN"))
    header = struct.pack(">BQ", 0x06, 64 * MiB)  # a long command frame announced as 64 MiB
    sent = 0
    try:
        s.sendall(header)
        while sent < 64 * MiB:
            s.sendall(b"\0" * MiB)
            sent += MiB
    except OSError:
        pass
    s.close()
    assert sent < 64 * MiB, "the core read a 64 MiB handshake command to its end"
    assert core_rss(core.state) - baseline < 50 * MiB
    assert core.client("red").robots() == []


def test_a_peer_without_a_valid_token_gets_nothing_and_is_logged_in_bulk(core: CoreHandle) -> None:
    """Defence: the ZAP handler refuses a handshake without a valid token; nothing of such a peer
    reaches the core's loop (not even a refusal), and its refused handshakes are logged once a beat
    per address with their count."""
    blue = core.client("blue")
    nobody = peer(core, None)  # a pyzmq DEALER with no credential at all
    guessers = [peer(core, f"guess-{i}-of-a-token") for i in range(30)]
    for p in [nobody, *guessers]:
        _send(p, P.request("hello", 1, {"token": core.token("blue")}))
    assert not nobody.sock.poll(1000)
    assert all(not p.sock.poll(200) for p in guessers)
    assert blue.robots() == []

    def logged() -> list[dict[str, Any]] | None:
        rows = [e for e in core.logged_events("refused") if e["data"].get("type") == "connect"]
        return rows if sum(e["data"]["count"] for e in rows) >= 30 else None

    rows = wait_for(logged, 10.0, "the refused handshakes in the log")
    assert len(rows) < 30  # in bulk, not one record per handshake
    assert {e["data"]["code"] for e in rows} == {"E_AUTH"} and {e["team"] for e in rows} == {None}
    # the hello from the peer with no credential never reached the core: no hello refusal either
    assert not [e for e in core.logged_events("refused") if e["data"].get("type") == "hello"]
    for p in [nobody, *guessers]:
        p.close()


def test_a_hello_must_use_the_token_the_connection_presented(core: CoreHandle) -> None:
    """Defence: the session's principal is the transport's: a connection that presented red's token
    cannot open a session with blue's (nor register blue's robots), and every frame of a session
    must come from a connection that presented the same principal."""
    red = peer(core, core.token("red"))
    reply = red.ask("hello", {"token": core.token("blue")})
    assert code(reply) == "E_AUTH" and "token" in reply["error"]["message"]
    assert code(red.ask("register", {"token": core.host_token("blue"), "robot_id": "b-1"})) == "E_AUTH"
    assert code(red.ask("register", {"token": core.token("blue"), "robot_id": "b-1"})) == "E_FORBIDDEN"
    assert red.own("hello", {"token": core.token("red")})["ok"]  # its own token: fine
    assert red.own("robots")["ok"]
    red.close()


# ------------------------------------------------------------------ decoding bounded
def test_frames_slow_to_decode_are_refused_and_the_core_serves_on(core: CoreHandle) -> None:
    """Defence: msgpack limits sized to the protocol (lengths, nesting, and a budget of maps and
    arrays per frame). 20 frames under 1 MiB that would each make 300,000 maps (or a 500,000-entry
    list) are refused with E_TOO_LARGE, sessionless or in a session, and a console is served
    between them. The longest loop turn is measured by bench/bench_transport.py."""
    blue = core.client("blue")
    red = peer(core, core.token("red"))  # a credential, no session yet
    slow = [P.request("radio", k, {"tag": 1, "data": [{}] * 300_000}) for k in range(10)]
    slow += [P.request("radio", 10 + k, {"tag": 1, "data": [None] * 500_000}) for k in range(10)]
    assert all(len(f) < P.MAX_FRAME for f in slow)
    for f in slow:
        red.sock.send(f)
    for k in range(20):
        assert code(red.reply(0)) == "E_TOO_LARGE"  # refused before the request id is read
        if k % 5 == 0:
            assert blue.robots() == []
    assert red.own("hello", {"token": core.token("red")})["ok"]
    for k, f in enumerate(slow[:3]):  # the same inside a session
        red.sock.send(P.request("radio", 100 + k, {"tag": 1, "data": [{}] * 300_000}, red.session))
        assert code(red.reply(0)) == "E_TOO_LARGE"
    assert red.own("robots")["ok"]  # the session survived


# ------------------------------------------------------------------ sessions
def test_a_second_hello_of_the_same_client_ends_its_old_session(core: CoreHandle) -> None:
    """Defence: hello's ``instance``. A console that reconnects says hello with the same principal
    and instance: its old session ends at once (no more events, its secret refused), while a
    teammate's console (another instance) is untouched."""
    instance = P.new_instance_id()
    old = peer(core, core.token("blue"))
    assert old.own("hello", {"token": core.token("blue"), "instance": instance})["ok"]
    assert old.own("watch", {"on": True})["ok"]
    mate = peer(core, core.token("blue"))
    assert mate.own("hello", {"token": core.token("blue"), "instance": P.new_instance_id()})["ok"]
    new = peer(core, core.token("blue"))
    assert new.own("hello", {"token": core.token("blue"), "instance": instance})["ok"]
    assert new.own("watch", {"on": True})["ok"]
    assert code(old.ask("robots", secret=old.session)) == "E_AUTH"
    assert mate.own("robots")["ok"] and new.own("robots")["ok"]
    ref = core.referee()
    ref.request("broadcast", message="is anyone there")
    wait_for(lambda: [m for m in new.listen(0.2) if m["type"] == "event" and m["body"]["topic"] == "broadcast"],
             5.0, "the broadcast at the new session")
    assert not [m for m in old.listen(0.5) + old.pushed
                if m["type"] == "event" and m["body"]["topic"] == "broadcast"]  # no push after the end
    # a short, guessable instance is refused with a sentence
    assert code(peer(core, core.token("blue")).ask("hello", {"token": core.token("blue"),
                                                             "instance": "1"})) == "E_FIELD"
    for p in (old, mate, new):
        p.close()


def test_the_clients_reconnect_ends_its_old_session(core: CoreHandle) -> None:
    """The friendly client sends its instance: after ``connect()`` (a reconnect) the old
    session's secret no longer works on the old connection's id."""
    c = core.client("red")
    first = c.session
    c.connect()
    assert c.session != first
    assert c.robots() == []
    assert core.referee().request("stats")["sessions_by"].get("red") == 1


# ------------------------------------------------------------------ connection flood
FD_LIMIT = 1024
FLOOD = 1124


@pytest.fixture
def small_core(tmp_path: Path) -> Iterator[CoreHandle]:
    """A core whose process may open only 1,024 files, soft and hard (a common default): it
    cannot raise the limit, so only its connection limits keep it reachable."""
    state = tmp_path / "state"
    state.mkdir()

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_NOFILE, (FD_LIMIT, FD_LIMIT))

    with open(state / "core.log", "ab") as log:
        proc = subprocess.Popen([sys.executable, "-m", "robo_comp.cli", "core", "--state", str(state), "--port", "0",
                                 "--heartbeat", "0.2", "--teams", "red,blue"], stdout=log, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, preexec_fn=limit)
    h = CoreHandle(state, None, proc)
    try:
        wait_for(lambda: (state / "core.json").exists() or proc.poll() is not None, 20.0, "the core's start")
        assert proc.poll() is None, (state / "core.log").read_text()[-2000:]
        yield h
    finally:
        h.close()


def _flood(address: str, target: tuple[str, int], opening: bytes, then: bytes = b"") -> list[socket.socket]:
    """:data:`FLOOD` TCP connections from ``address`` that each send ``opening`` (a handshake),
    and ``then`` once the core's ``WELCOME`` has come (the rest of a PLAIN handshake), then
    nothing."""
    socks = []
    for _ in range(FLOOD):
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        s.bind((address, 0))
        s.setblocking(False)
        s.connect_ex(target)
        socks.append(s)
    t_end = time.monotonic() + 10.0
    sending = list(socks)
    welcomed: dict[socket.socket, bytes] = {}
    while (sending or welcomed) and time.monotonic() < t_end:  # each sends its handshake once connected
        left = []
        for s in sending:
            try:
                s.send(opening)
            except BlockingIOError:
                left.append(s)
            except OSError:  # refused or cut by the core: done
                pass
            else:
                if then:
                    welcomed[s] = b""
        sending = left
        for s, got in list(welcomed.items()):
            try:
                chunk = s.recv(4096)
            except BlockingIOError:
                continue
            except OSError:
                chunk = b""
            if not chunk:  # cut by the core
                del welcomed[s]
            elif b"WELCOME" in got + chunk:
                with contextlib.suppress(OSError):
                    s.send(then)
                del welcomed[s]
            else:
                welcomed[s] = got + chunk
        time.sleep(0.05)
    return socks


def test_a_connection_flood_is_cut_and_the_match_goes_on(small_core: CoreHandle) -> None:
    """Defence: connection limits per peer address and in total (a socket monitor in the core's
    loop cuts the excess at once), the PLAIN handshake (no credential, no connection),
    HANDSHAKE_IVL, and the open-file limit raised where allowed. Against a core limited to 1,024
    descriptors: 1,124 connections from one address that complete a handshake without a credential
    (the audit's attack), then 1,124 from another that present red's valid token and sit idle. A new
    console still connects, a robot host goes on, and the cuts are logged in bulk."""
    core = small_core
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if hard < 2 * FLOOD + 200:
        pytest.skip(f"this test process may open only {hard} files")
    resource.setrlimit(resource.RLIMIT_NOFILE, (max(soft, 2 * FLOOD + 200), hard))
    core.robots("red", 1)
    ref = core.referee()
    tag = wait_robots(ref, 1)[0]["tag"]
    target = router_address(core.state)
    flood: list[socket.socket] = []
    try:
        flood += _flood("127.0.0.2", target, zmtp_open("NULL"))
        flood += _flood("127.0.0.3", target, zmtp_open("PLAIN", core.token("red").encode()), zmtp_initiate())
        blue = core.client("blue")  # a new client gets in during the flood
        assert blue.robots() == [] and blue.role == "team"
        assert ref.give(tag, "goTo", [3, 3])["task_id"] >= 1  # the match goes on
        assert ref.monitor(tag)["status"] == "connected"

        def logged() -> list[dict[str, Any]] | None:
            rows = [e for e in core.logged_events("refused") if e["data"].get("type") == "connect"]
            # a bulk of them (how many depends on how fast libzmq closes those it refuses itself)
            return rows if sum(e["data"]["count"] for e in rows) >= 100 else None

        rows = wait_for(logged, 10.0, "the cut connections in the log")
        assert len(rows) < 50 and {e["data"]["code"] for e in rows} <= {"E_RATE", "E_AUTH"}
        assert {e["data"]["address"] for e in rows} <= {"127.0.0.2", "127.0.0.3"}
        stats = ref.request("stats")
        assert stats["connection_limit"] <= FD_LIMIT - 128 and stats["connections_cut"] >= 100
        assert stats["connections"] <= stats["connection_limit"]
    finally:
        for s in flood:
            s.close()


def test_a_valid_credential_refused_for_room_is_told_so_not_called_invalid() -> None:
    """The ZAP handler's two refusals reach the client apart (real PLAIN sockets, the core's
    handler): a made-up token is "not valid" (E_AUTH), a valid one the connection limits turn away
    (the core full, or the team's share of sessions held) is told so (E_RATE), not sent to check
    its token file."""
    import threading

    from robo_comp.errors import AuthError, RateLimitError
    from robo_comp.protocol.curve import (HANDSHAKE_EVENTS, ZapHandler, handshake_error, secure_plain_client,
                                          secure_plain_server)
    from robo_comp.teams.tokens import Principal

    def lookup(token: str) -> Principal:
        if token != "a-valid-token-of-red":
            raise AuthError("not valid")
        return Principal("team", "red")

    ctx = zmq.Context()
    zap = ZapHandler(ctx, lookup=lookup, admit=lambda who: "the core is full")
    router = ctx.socket(zmq.ROUTER)
    secure_plain_server(router)
    port = router.bind_to_random_port("tcp://127.0.0.1")
    done = threading.Event()

    def serve() -> None:
        while not done.is_set():
            if zap.sock.poll(50):
                zap.serve()

    server = threading.Thread(target=serve, daemon=True)
    server.start()

    def outcome(token: str) -> Exception | None:
        d = ctx.socket(zmq.DEALER)
        d.setsockopt(zmq.LINGER, 0)
        secure_plain_client(d, token)
        mon = d.get_monitor_socket(HANDSHAKE_EVENTS)
        d.connect(f"tcp://127.0.0.1:{port}")
        try:
            assert mon.poll(10_000), "no handshake event"
            return handshake_error(mon.recv_multipart(), curve=False)
        finally:
            d.disable_monitor()
            mon.close(0)
            d.close(0)

    try:
        no_room, invalid = outcome("a-valid-token-of-red"), outcome("a-made-up-token")
    finally:
        done.set()
        server.join()
        router.close(0)
        zap.close()
        ctx.term()
    assert isinstance(no_room, RateLimitError) and "no room" in no_room.message, no_room
    assert isinstance(invalid, AuthError) and "not valid" in invalid.message, invalid
    assert sum(row.count for row in zap.take_refused().values()) == 2  # both logged by the core, in bulk

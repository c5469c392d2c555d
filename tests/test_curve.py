"""CurveZMQ (``robo-comp keys`` + ``robo-comp core --curve``) with real processes.

A client with its team's certificate talks to the core as without CURVE; one without a
certificate, or with a key the core does not know, never completes the handshake (no reply, no
event) while the core keeps serving the others.
"""
from __future__ import annotations

import asyncio
import json
import stat
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import zmq

from conftest import CoreHandle, wait_for, wait_robots
from robo_comp.client import Client
from robo_comp.protocol.curve import ENV_CERT, ENV_CORE_KEY, create_keys
from robo_comp.errors import AuthError, ConnectionLostError, FieldError, TimeoutError_
from robo_comp.launch import start_core, start_robots


def robo_comp(*args: str, timeout: float = 30.0) -> subprocess.CompletedProcess[str]:
    """Run ``robo-comp ARGS`` and capture its output."""
    return subprocess.run([sys.executable, "-m", "robo_comp.cli", *args], capture_output=True, text=True,
                          timeout=timeout, stdin=subprocess.DEVNULL)


@pytest.fixture
def curve_core(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[CoreHandle]:
    """A ``--curve`` core (teams red and blue) whose keys ``robo-comp keys`` made."""
    monkeypatch.delenv(ENV_CERT, raising=False)
    monkeypatch.delenv(ENV_CORE_KEY, raising=False)
    state = tmp_path / "state"
    out = robo_comp("keys", "--state", str(state), "--teams", "red,blue")
    assert out.returncode == 0, out.stderr
    proc = start_core(state, "--heartbeat", "0.2", "--teams", "red,blue", "--curve")
    h = CoreHandle(state, None, proc)
    yield h
    h.close()


def test_keys_are_made_once_with_private_secrets(tmp_path: Path) -> None:
    state = tmp_path / "s"
    out = robo_comp("keys", "--state", str(state), "--teams", "red,blue")
    assert out.returncode == 0, out.stderr
    assert "red.key_secret" in out.stdout and "core.key" in out.stdout
    keys = state / "keys"
    for name in ("core", "red", "blue", "referee", "organiser"):
        assert (keys / f"{name}.key").is_file()
        assert stat.S_IMODE((keys / f"{name}.key_secret").stat().st_mode) == 0o600
    before = {p.name: p.read_bytes() for p in keys.iterdir()}
    assert create_keys(state, ["red", "blue", "green"]) == {"core": False, "red": False, "blue": False,
                                                            "green": True, "referee": False, "organiser": False}
    assert all((keys / n).read_bytes() == b for n, b in before.items())  # existing keys kept


def test_curve_core_without_keys_says_what_to_run(tmp_path: Path) -> None:
    out = robo_comp("core", "--state", str(tmp_path / "s"), "--port", "0", "--curve")
    assert out.returncode == 2
    assert "run robo-comp keys --state" in out.stderr


def test_curve_match(curve_core: CoreHandle, tmp_path: Path) -> None:
    state = curve_core.state
    info = json.loads((state / "core.json").read_text())
    assert info["curve"] is True and len(info["curve_public"]) == 40
    keys = state / "keys"
    # a robot host with the organiser's certificate, given explicitly (a team's key never hosts robots)
    curve_core.procs.append(start_robots(state, "red", 2, "--curve-cert", str(keys / "organiser.key_secret"),
                                         "--core-key", str(keys / "core.key")))
    good = curve_core.client("red")  # a state folder: the token's team certificate is found there
    assert good.curve is not None
    rows = wait_robots(good, 2)
    sub = good.subscribe()
    plain_ctx = zmq.Context()
    plain_sub = plain_ctx.socket(zmq.SUB)
    plain_sub.setsockopt(zmq.LINGER, 0)
    plain_sub.setsockopt(zmq.SUBSCRIBE, b"")
    plain_sub.connect(info["pub"])
    time.sleep(0.3)  # slow joiner
    assert good.give(rows[0]["tag"], "goTo", [4, 4])["task_id"] >= 1
    assert sub.poll(3000), "a SUB with the right key gets events"
    # no certificate, and a certificate the core does not know: no reply, ever
    stranger = tmp_path / "stranger"
    create_keys(stranger, ["red"])
    token = curve_core.token("red")
    # (said at once when the handshake fails with a reason, else when the hello times out)
    with pytest.raises((TimeoutError_, ConnectionLostError), match="--curve"):
        Client(info["router"], token, timeout=1.0)
    with pytest.raises((TimeoutError_, AuthError), match="--curve-cert"):
        Client(info["router"], token, timeout=1.0, curve_cert=stranger / "keys" / "red.key_secret",
               core_key=keys / "core.key")
    while sub.poll(0):  # events are flowing now: the keyed SUB gets the next ones, the plain one none
        sub.recv_multipart()
    assert good.give(rows[1]["tag"], "goTo", [5, 4])["task_id"] >= 1
    assert sub.poll(3000), "a SUB with the right key gets the new events"
    assert not plain_sub.poll(1000), "a SUB without a key gets no event"
    plain_sub.close(0)
    plain_ctx.term()
    assert len(good.robots()) == 2  # the core kept serving the good client
    # the public feed and the other commands, from other processes and clients
    out = robo_comp("ctl", "--core", info["router"], "--token-file", str(state / "teams/red.token"),
                    "--curve-cert", str(keys / "red.key_secret"), "--core-key", str(keys / "core.key"),
                    "--json", "robots")
    assert out.returncode == 0, out.stderr
    assert sorted(r["tag"] for r in json.loads(out.stdout)) == sorted(r["tag"] for r in rows)
    with pytest.raises(FieldError, match="--core-key"):
        Client(info["router"], token, curve_cert=keys / "red.key_secret")
    # a team's key lets in that team only: blue's key with red's token is refused at hello
    with pytest.raises(AuthError, match="team blue's key"):
        Client(info["router"], token, timeout=3.0, curve_cert=keys / "blue.key_secret", core_key=keys / "core.key")
    referee_keyed = Client(info["router"], token, timeout=3.0, curve_cert=keys / "referee.key_secret",
                           core_key=keys / "core.key")  # the organiser's key may carry any token
    assert len(referee_keyed.robots()) == 2
    referee_keyed.close()


def test_console_link_and_wall_over_curve(curve_core: CoreHandle, monkeypatch: pytest.MonkeyPatch) -> None:
    from robo_comp.link import CoreLink
    from robo_comp.wall.app import LiveSource
    from robo_comp.view.model import MatchView

    state = curve_core.state
    keys = state / "keys"
    info = json.loads((state / "core.json").read_text())

    async def console() -> None:  # the environment, as a console started by 'robo-comp team' uses it
        monkeypatch.setenv(ENV_CERT, str(keys / "blue.key_secret"))
        monkeypatch.setenv(ENV_CORE_KEY, str(keys / "core.key"))
        link = CoreLink(info["router"], curve_core.token("blue"))
        link.start()
        for _ in range(100):
            if link.connected:
                break
            await asyncio.sleep(0.05)
        assert link.connected and link.team == "blue"
        assert (await link.request("robots"))["robots"] == []
        await link.close()

    asyncio.run(console())
    monkeypatch.delenv(ENV_CERT)
    monkeypatch.delenv(ENV_CORE_KEY)
    src = LiveSource(str(state), curve_core.token("referee"))  # the referee's certificate, from the state folder
    try:
        model = MatchView()
        src.start(model)
        assert src.client.curve is not None and src.client.role == "referee"
        wait_for(lambda: src.client.robots() == [], 2.0, "a reply to the wall")
    finally:
        src.close()

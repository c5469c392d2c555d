"""Finding the core on the LAN by name (mDNS with zeroconf), kept on loopback: every test sets
``ROBO_COMP_MDNS_INTERFACES=127.0.0.1`` (zeroconf's ``interfaces=["127.0.0.1"]``, IPv4 only), and
the cores bind 127.0.0.1, so no multicast goes out on any other interface."""
from __future__ import annotations

import itertools
import os
import signal
import subprocess
import sys

import pytest

pytest.importorskip("zeroconf")

from conftest import wait_for, wait_robots  # noqa: E402
from robo_comp import discovery  # noqa: E402
from robo_comp.client import Client, resolve_core  # noqa: E402
from robo_comp.errors import FieldError, UnavailableError  # noqa: E402
from robo_comp.launch import start_core, stop_all  # noqa: E402
from robo_comp.testing import Match  # noqa: E402

_n = itertools.count()


@pytest.fixture
def name(monkeypatch: pytest.MonkeyPatch) -> str:
    """A core name of this test's own, with mDNS pinned to loopback."""
    monkeypatch.setenv(discovery.ENV_INTERFACES, "127.0.0.1")
    monkeypatch.setattr(discovery, "_cache", {})
    return f"rc-test-{os.getpid()}-{next(_n)}"


def test_an_advertised_core_is_found_by_name_by_robots_and_consoles(tmp_path, name):
    state = tmp_path / "state"
    proc = start_core(state, "--teams", "red,blue", "--heartbeat", "0.5", "--advertise", name)
    match = Match(state, None, proc)
    robots = None
    try:
        wait_for(lambda: f"advertised on the LAN as mdns:{name}" in (state / "core.log").read_text(), 20,
                 "the core to take its name")
        found = discovery.find(name)
        assert found.url == resolve_core(str(state)) and found.curve is False and found.pub_port
        # a robot host and a console given only the name
        robots = subprocess.Popen([sys.executable, "-m", "robo_comp.cli", "robots", "--core", f"mdns:{name}",
                                   "--token-file", str(match.host_token_file("red")), "--count", "1"],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        with Client(f"mdns:{name}", match.token("red"), client="test") as red:
            assert wait_robots(red, 1)[0]["team"] == "red"
    finally:
        stop_all([p for p in (robots,) if p is not None])
        proc.send_signal(signal.SIGTERM)  # the core withdraws its name as it stops
        proc.wait(15)
        match.close()
    with pytest.raises(UnavailableError, match=f"no core named '{name}' answered"):
        discovery.find(name, timeout=1.0)


def test_a_core_is_not_advertised_unless_asked_and_names_are_checked(tmp_path, name, capsys):
    state = tmp_path / "state"
    proc = start_core(state, "--teams", "red,blue")
    try:
        with pytest.raises(UnavailableError, match="--advertise"):
            discovery.find(name, timeout=1.0)
    finally:
        proc.terminate()
        proc.wait(15)
    # one name, one core: a second core asking for a name already answered for is refused
    first = discovery.advertise(name, "127.0.0.1", 5999, 6000)
    try:
        with pytest.raises(FieldError, match="another core already answers"):
            discovery.advertise(name, "127.0.0.1", 6001, 6002)
        assert discovery.find(name).url == "tcp://127.0.0.1:5999"
    finally:
        first.close()
    for bad in ("", "has space", "dots.in.it", "x" * 64):
        with pytest.raises(FieldError, match="cannot name a core"):
            discovery.check_name(bad)
    from robo_comp.cli import main

    assert main(["ctl", "--core", "mdns:bad name", "--token", "t", "robots"]) == 2
    assert "cannot name a core" in capsys.readouterr().err

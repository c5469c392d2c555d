"""The sandbox's second wall (robo_comp/sandbox/oswall.py; docs/security.md, "Hostile uploads").

Team code gets past the policy through a planted hole (``Limits(test_policy_hole=True)``: the
real ``os`` and ``socket`` modules among its builtins) and goes around the rlimits (it closes its standard
descriptors to open new ones). Inside the OS layer it still cannot reach the host's network, read
or write a file outside, or see another team's sandbox process; with the layer turned off the
same code does all of that (so the test can fail).
"""
from __future__ import annotations

import os
import socket
from collections.abc import Iterator
from typing import Any

import pytest

import robo_comp
from robo_comp.errors import RoboCompError, UnavailableError
from robo_comp.sandbox import oswall
from robo_comp.sandbox.parent import Limits, Sandbox, TaskDone
from robo_comp.testing import plugin

PKG_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(robo_comp.__file__)))

HOLE = '''
MANIFEST = {"name": "hole", "version": "1.0", "kind": "extension",
            "tasks": {"attack": {"description": "through a planted hole",
                                 "args": [{"name": "port", "type": "int"}, {"name": "pid", "type": "int"}]}}}

# no import: the hole puts the real os and socket modules among the builtins
def attack(robot, port, pid):
    for fd in (0, 1, 2):  # around RLIMIT_NOFILE: free descriptors to open new ones with
        try:
            os.close(fd)
        except OSError:
            pass
    out = {}
    def attempt(name, fn):
        try:
            fn()
            out[name] = "done"
        except BaseException as e:
            out[name] = "refused: " + str(e)[:100]
    def tcp():
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        s.settimeout(3)
        try:
            s.connect(("127.0.0.1", port))
        finally:
            s.close()
    def read():
        os.close(os.open("/etc/passwd", os.O_RDONLY))
    def write():
        os.close(os.open("/tmp/robo_comp_os_sandbox_test", os.O_WRONLY | os.O_CREAT, 0o600))
        os.unlink("/tmp/robo_comp_os_sandbox_test")
    attempt("tcp", tcp)
    attempt("read", read)
    attempt("write", write)
    attempt("signal", lambda: os.kill(pid, 0))
    attempt("fork", lambda: os.fork() or 0)
    return out
'''


@pytest.fixture()
def listener() -> Iterator[int]:
    """A TCP server of the host on 127.0.0.1: the port team code tries to reach."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    try:
        yield srv.getsockname()[1]
    finally:
        srv.close()


def needs_bwrap() -> None:
    if plugin.OS_SANDBOX_OFF is not None:
        pytest.skip(f"the OS sandbox cannot run here: {plugin.OS_SANDBOX_OFF}")
    try:
        oswall.check(PKG_ROOT)
    except RoboCompError as e:
        pytest.skip(e.message)


def attack(port: int) -> tuple[dict[str, str], bool]:
    """Red's team code through the hole, against blue's sandbox process on the same host."""
    limits = Limits(test_policy_hole=True)
    blue = Sandbox("blue", [201], None, limits)
    red = Sandbox("red", [101], None, limits)
    try:
        blue.load("idle.py", 'MANIFEST = {"name": "idle", "version": "1.0", "kind": "extension", '
                             '"tasks": {"idle": {"description": "x", "args": []}}}\ndef idle(robot):\n    return 1\n')
        assert blue.proc is not None
        target = blue.pid
        red.load("hole.py", HOLE)
        rec = red.run_task(101, "attack", [port, target])
        assert isinstance(rec, TaskDone), rec
        return rec.result, red.os_sandbox
    finally:
        red.close()
        blue.close()


def test_team_code_through_a_hole_in_the_policy_is_still_walled_in(listener: int) -> None:
    needs_bwrap()
    got, walled = attack(listener)
    assert walled
    # the host's server listens on 127.0.0.1:port; the sandbox's 127.0.0.1 is its own loopback
    assert got["tcp"].startswith("refused") and ("Connection refused" in got["tcp"]
                                                  or "unreachable" in got["tcp"]), got
    assert got["read"].startswith("refused") and "No such file" in got["read"], got
    assert got["write"].startswith("refused"), got
    assert got["signal"].startswith("refused") and "No such process" in got["signal"], got
    assert got["fork"].startswith("refused"), got


def test_the_hole_is_real_without_the_os_layer(listener: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """The same code with ``ROBO_COMP_OS_SANDBOX=off``: the planted hole and the freed descriptors
    let it reach the host's network, read /etc and signal blue's sandbox (what the layer stops)."""
    if os.geteuid() != 0:
        pytest.skip("the comparison is made as root (the child then runs as nobody, like blue's)")
    monkeypatch.setenv(oswall.ENV, "off")
    got, walled = attack(listener)
    assert not walled
    assert got["tcp"] == "done" and got["read"] == "done" and got["signal"] == "done", got
    assert got["fork"].startswith("refused")  # RLIMIT_NPROC, the first wall, holds by itself


def test_without_bwrap_team_code_does_not_run(monkeypatch: pytest.MonkeyPatch, tmp_path: Any) -> None:
    """No bwrap and no ``ROBO_COMP_OS_SANDBOX=off``: the sandbox refuses to start, saying how to
    install it and how the organiser turns the layer off."""
    monkeypatch.delenv(oswall.ENV, raising=False)
    monkeypatch.setenv("PATH", str(tmp_path))  # no bwrap on it
    with pytest.raises(UnavailableError) as e:
        Sandbox("red", [101])
    assert "bwrap is not installed" in e.value.message and f"{oswall.ENV}=off" in e.value.message

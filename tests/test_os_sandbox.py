"""The sandbox's second wall (robo_comp/sandbox/oswall.py; docs/security.md, "Hostile uploads").

Team code gets past the policy through a planted hole (``Limits(test_policy_hole=True)``: the
real ``os``, ``socket`` and ``ctypes`` modules among its builtins) and goes around the rlimits (it
closes its standard descriptors to open new ones). Inside the OS layer it still cannot reach the
host's network or a UNIX socket of the host, read or write a file outside, or see another team's
sandbox process; with the layer turned off the same code does all of that (so the test can fail).
Through ``ctypes`` it makes system calls the seccomp filter refuses (sandbox/sysfilter.py): every
one fails with ``EPERM`` and the sandbox goes on; with bwrap but without the filter the same calls
reach the kernel (sockets made, another process's memory read, a new program run).
"""
from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from typing import Any

import pytest

import robo_comp
from robo_comp.errors import RoboCompError, UnavailableError
from robo_comp.sandbox import oswall
from robo_comp.sandbox.parent import Limits, Sandbox, TaskDone, TaskFailed
from robo_comp.testing import plugin, wait_robots

PKG_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(robo_comp.__file__)))

HOLE = '''
MANIFEST = {"name": "hole", "version": "1.0", "kind": "extension",
            "tasks": {"attack": {"description": "the host's network, files and processes",
                                 "args": [{"name": "port", "type": "int"}, {"name": "pid", "type": "int"},
                                          {"name": "unix_path", "type": "str"}]},
                      "calls": {"description": "system calls", "args": []},
                      "run_program": {"description": "a new program", "args": []}}}

NR = @NR@  # this machine's system call numbers (from the test)

# no import: the hole puts the real os, socket and ctypes modules among the builtins
def free_descriptors():
    for fd in (0, 1, 2):  # around RLIMIT_NOFILE: free descriptors to open new ones with
        try:
            os.close(fd)
        except OSError:
            pass

def attempt(out, name, fn):
    try:
        fn()
        out[name] = "done"
    except BaseException as e:
        out[name] = "refused: " + str(e)[:100]

def attack(robot, port, pid, unix_path):
    free_descriptors()
    out = {}
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
    def unix():
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            s.connect(unix_path)
        finally:
            s.close()
    attempt(out, "tcp", tcp)
    attempt(out, "unix", unix)
    attempt(out, "read", read)
    attempt(out, "write", write)
    attempt(out, "signal", lambda: os.kill(pid, 0))
    attempt(out, "fork", lambda: os.fork() or 0)
    return out

def calls(robot):
    free_descriptors()
    libc = ctypes.CDLL(None, use_errno=True)
    out = {}
    def raw(name, *args):
        def call():
            ctypes.set_errno(0)
            wide = [ctypes.c_long(a) if isinstance(a, int) else a for a in args]  # whole registers
            if libc.syscall(ctypes.c_long(NR[name]), *wide) < 0:
                err = ctypes.get_errno()
                raise OSError(err, os.strerror(err))
        attempt(out, name, call)
    attempt(out, "socket AF_UNIX", lambda: socket.socket(socket.AF_UNIX, socket.SOCK_STREAM).close())
    attempt(out, "socket AF_INET", lambda: socket.socket(socket.AF_INET, socket.SOCK_DGRAM).close())
    attempt(out, "socket AF_NETLINK", lambda: socket.socket(socket.AF_NETLINK, socket.SOCK_RAW, 0).close())
    attempt(out, "socketpair", lambda: [s.close() for s in socket.socketpair()])
    secret = ctypes.create_string_buffer(b"another process's memory")
    copy = ctypes.create_string_buffer(32)
    def iovec(buf, n):
        return ctypes.create_string_buffer(ctypes.addressof(buf).to_bytes(8, "little") + n.to_bytes(8, "little"), 16)
    raw("process_vm_readv", os.getpid(), iovec(copy, 24), 1, iovec(secret, 24), 1, 0)
    raw("ptrace", 16, 999999, 0, 0)  # PTRACE_ATTACH to a process that does not exist
    raw("unshare", 0x10000000)  # CLONE_NEWUSER
    raw("setns", 0, 0)
    raw("mount", b"none", b"/", b"tmpfs", 0, None)
    raw("keyctl", 0, -3, 0)  # KEYCTL_GET_KEYRING_ID of the session keyring
    raw("bpf", 0, None, 0)
    raw("perf_event_open", None, 0, -1, -1, 0)
    raw("io_uring_setup", 1, None)
    raw("kexec_load", 0, 0, None, 0)
    return out

def run_program(robot):
    try:
        os.execv("/bin/sh", ["sh", "-c", "exit 42"])
    except OSError as e:
        return "refused: " + str(e)
'''
#: Refused with EPERM by the filter; the rest of the kernel test shows what they do without it.
FILTERED = ("socket AF_UNIX", "socket AF_INET", "socket AF_NETLINK", "socketpair", "process_vm_readv",
            "ptrace", "unshare", "setns", "mount", "keyctl", "bpf", "perf_event_open", "io_uring_setup",
            "kexec_load")
EPERM = "refused: [Errno 1] Operation not permitted"


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


@pytest.fixture()
def unix_listener() -> Iterator[str]:
    """A UNIX socket server of the host at a path that the child's user (``nobody`` as root) could
    reach without the layer."""
    folder = tempfile.mkdtemp(prefix="robo_comp_os_sandbox_", dir="/tmp")
    os.chmod(folder, 0o755)
    path = os.path.join(folder, "host.sock")
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    srv.bind(path)
    os.chmod(path, 0o777)
    srv.listen(8)
    try:
        yield path
    finally:
        srv.close()
        shutil.rmtree(folder, ignore_errors=True)


def hole() -> str:
    """The team module that uses the hole, with this machine's system call numbers."""
    import pyseccomp

    names = {name.split()[0] for name in FILTERED}
    return HOLE.replace("@NR@", repr({n: pyseccomp.resolve_syscall(pyseccomp.Arch.NATIVE, n) for n in names}))


def needs_bwrap() -> None:
    if plugin.OS_SANDBOX_OFF is not None:
        pytest.skip(f"the OS sandbox cannot run here: {plugin.OS_SANDBOX_OFF}")
    try:
        oswall.check(PKG_ROOT)
    except RoboCompError as e:
        pytest.skip(e.message)


def attack(port: int, unix_path: str) -> tuple[dict[str, str], bool]:
    """Red's team code through the hole, against blue's sandbox process on the same host."""
    limits = Limits(test_policy_hole=True)
    blue = Sandbox("blue", [201], None, limits)
    red = Sandbox("red", [101], None, limits)
    try:
        blue.load("idle.py", 'MANIFEST = {"name": "idle", "version": "1.0", "kind": "extension", '
                             '"tasks": {"idle": {"description": "x", "args": []}}}\ndef idle(robot):\n    return 1\n')
        assert blue.proc is not None
        target = blue.pid
        red.load("hole.py", hole())
        rec = red.run_task(101, "attack", [port, target, unix_path])
        assert isinstance(rec, TaskDone), rec
        return rec.result, red.os_sandbox
    finally:
        red.close()
        blue.close()


def attack_kernel() -> tuple[dict[str, str], TaskDone | TaskFailed | None]:
    """Red's system calls through the hole, then a new program; the sandbox's answers."""
    with Sandbox("red", [101], None, Limits(test_policy_hole=True)) as red:
        assert red.os_sandbox
        red.load("hole.py", hole())
        rec = red.run_task(101, "calls", [])
        assert isinstance(rec, TaskDone), rec
        return rec.result, red.run_task(101, "run_program", [])


def test_team_code_through_a_hole_in_the_policy_is_still_walled_in(listener: int, unix_listener: str) -> None:
    needs_bwrap()
    got, walled = attack(listener, unix_listener)
    assert walled
    # the host's server listens on 127.0.0.1:port; the sandbox cannot even make a socket
    assert got["tcp"] == got["unix"] == EPERM, got
    assert got["read"].startswith("refused") and "No such file" in got["read"], got
    assert got["write"].startswith("refused"), got
    assert got["signal"].startswith("refused") and "No such process" in got["signal"], got
    assert got["fork"].startswith("refused"), got


def test_the_hole_is_real_without_the_os_layer(listener: int, unix_listener: str,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """The same code with ``ROBO_COMP_OS_SANDBOX=off``: the planted hole and the freed descriptors
    let it reach the host's network and UNIX socket, read /etc and signal blue's sandbox (what the
    layer stops)."""
    if os.geteuid() != 0:
        pytest.skip("the comparison is made as root (the child then runs as nobody, like blue's)")
    monkeypatch.setenv(oswall.ENV, "off")
    got, walled = attack(listener, unix_listener)
    assert not walled
    assert got["tcp"] == got["unix"] == got["read"] == got["signal"] == "done", got
    assert got["fork"].startswith("refused")  # RLIMIT_NPROC, the first wall, holds by itself


def test_the_seccomp_filter_refuses_system_calls_with_eperm_and_the_sandbox_goes_on() -> None:
    """Through ``ctypes``: every call on the filter's list fails with EPERM (an ordinary Python
    error for team code, not a kill), and ``execve`` once the child runs too."""
    needs_bwrap()
    got, program = attack_kernel()
    assert {name: got[name] for name in FILTERED} == {name: EPERM for name in FILTERED}
    assert isinstance(program, TaskDone) and program.result == EPERM, program


def test_without_the_filter_the_same_calls_reach_the_kernel(monkeypatch: pytest.MonkeyPatch) -> None:
    """bwrap's namespaces alone, the filter left out: the same code makes sockets (its own
    network namespace's), reads a process's memory with ``process_vm_readv`` (its own, here),
    gets past ``ptrace``, ``setns``, ``unshare``, ``perf_event_open`` and ``io_uring_setup`` to
    the kernel's own checks of their arguments, and replaces the sandbox child by a shell that
    exits with 42."""
    needs_bwrap()
    monkeypatch.setattr(oswall, "wall", lambda pkg_root: oswall.Wall(pkg_root, None))
    got, program = attack_kernel()
    for name in ("socket AF_UNIX", "socket AF_INET", "socket AF_NETLINK", "socketpair", "process_vm_readv"):
        assert got[name] == "done", got
    assert got["ptrace"] == "refused: [Errno 3] No such process", got
    assert got["setns"] == "refused: [Errno 9] Bad file descriptor", got
    assert got["unshare"] == "refused: [Errno 22] Invalid argument", got
    assert got["perf_event_open"] == got["io_uring_setup"] == "refused: [Errno 14] Bad address", got
    assert isinstance(program, TaskFailed) and "code 42" in program.message, program


def test_without_bwrap_team_code_does_not_run(monkeypatch: pytest.MonkeyPatch, tmp_path: Any) -> None:
    """No bwrap and no ``ROBO_COMP_OS_SANDBOX=off``: the sandbox refuses to start, saying how to
    install it and how the organiser turns the layer off."""
    monkeypatch.delenv(oswall.ENV, raising=False)
    monkeypatch.setenv("PATH", str(tmp_path))  # no bwrap on it
    with pytest.raises(UnavailableError) as e:
        Sandbox("red", [101])
    assert "bwrap is not installed" in e.value.message and "--os-sandbox off" in e.value.message


def test_without_libseccomp_team_code_does_not_run() -> None:
    """A machine without libseccomp (its file made empty for one process): the sandbox refuses
    to start, saying what is missing and how the organiser turns the layer off."""
    needs_bwrap()
    import pyseccomp  # noqa: F401  (loads the library, so that its file shows in our memory map)

    with open("/proc/self/maps") as f:
        lib = next(line.split()[-1] for line in f if "libseccomp.so" in line)
    probe = ("from robo_comp.errors import RoboCompError\n"
             "from robo_comp.sandbox.parent import Sandbox\n"
             "try:\n    Sandbox('red', [101])\nexcept RoboCompError as e:\n    print(e.message)\n")
    env = {k: v for k, v in os.environ.items() if k != oswall.ENV}
    r = subprocess.run(["bwrap", "--dev-bind", "/", "/", "--ro-bind", "/dev/null", lib, "--",
                        sys.executable, "-c", probe], capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == 0, r.stderr
    assert "libseccomp is not installed" in r.stdout and "--os-sandbox off" in r.stdout, r.stdout


def robo_comp_without_bwrap(tmp_path: Any, *args: str, **env: str) -> subprocess.CompletedProcess[str]:
    """``robo-comp ARGS`` as a real process on a machine without bwrap (a PATH without it)."""
    empty = tmp_path / "no-bwrap"
    empty.mkdir(exist_ok=True)
    full = {k: v for k, v in os.environ.items() if k != oswall.ENV} | {"PATH": str(empty)} | env
    return subprocess.run([sys.executable, "-m", "robo_comp.cli", *args], capture_output=True, text=True,
                          timeout=60, env=full, stdin=subprocess.DEVNULL)


def test_a_robot_host_that_cannot_wall_team_code_stops_at_start_in_one_sentence(tmp_path: Any) -> None:
    """``robo-comp robots`` checks the layer before it connects: without bwrap it stops (exit
    code 2) with one sentence naming what is missing and both ways out, not at a team's first
    upload; ``--os-sandbox on`` wins over ``ROBO_COMP_OS_SANDBOX=off`` in its environment."""
    for extra, env in (((), {}), (("--os-sandbox", "on"), {oswall.ENV: "off"})):
        r = robo_comp_without_bwrap(tmp_path, "robots", "--core", str(tmp_path / "no-core"), "--token", "x",
                                    *extra, **env)
        assert r.returncode == 2, (r.stdout, r.stderr)
        said = r.stderr.strip()
        assert len(said.splitlines()) == 1 and said.count(". ") == 0, said
        assert said.startswith("robo-comp robots: team code runs only inside the OS sandbox"), said
        assert "bwrap is not installed" in said and "apt-get install bubblewrap" in said, said
        assert "--os-sandbox off" in said, said


def test_a_league_run_that_cannot_wall_team_code_stops_before_its_first_match(tmp_path: Any) -> None:
    r = robo_comp_without_bwrap(tmp_path, "league", "run", str(tmp_path / "season"), "--os-sandbox", "on")
    assert r.returncode == 2 and "robo-comp league: team code runs only inside the OS sandbox" in r.stderr, r
    assert "bwrap is not installed" in r.stderr and not (tmp_path / "season").exists()


def test_os_sandbox_off_runs_team_code_without_the_layer_and_says_so(core: Any, tmp_path: Any,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """The organiser's choice, made on the command line: a host on a machine without bwrap,
    started with ``--os-sandbox off``, says so at start and runs an upload (without the option
    the upload would be refused: see the test above)."""
    empty = tmp_path / "no-bwrap"
    empty.mkdir()
    monkeypatch.setenv("PATH", str(empty))
    monkeypatch.delenv(oswall.ENV, raising=False)
    core.robots("red", 1, "--os-sandbox", "off")
    red = core.client("red", timeout=30.0)
    tag = wait_robots(red, 1)[0]["tag"]
    module = ('MANIFEST = {"name": "hello", "version": "1", "kind": "extension", '
              '"tasks": {"hello": {"description": "x", "args": []}}}\ndef hello(robot):\n    return 1\n')
    out = red.upload([tag], "hello.py", module)
    assert out["ok"], out
    assert f"robo-comp robots: {oswall.OFF}" in (core.state / "robots-red.log").read_text()

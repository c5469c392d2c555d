"""The sandbox's second wall: the child runs inside bubblewrap (``bwrap``), below the policy.

RestrictedPython and the rlimits are the first wall (docs/sandbox.md). Should team code ever get
past the policy to a CPython primitive (a bug in CPython, RestrictedPython or our policy), this
layer still holds, because the kernel enforces it:

* **no network**: a network namespace of its own with no interface up (no TCP/UDP to anything,
  not even the host's ``127.0.0.1``; abstract UNIX sockets are per namespace too);
* **a read-only, minimal filesystem**: an empty root with read-only binds of ``/usr``, the
  Python installation, the virtualenv and the robo_comp package only; no ``/etc``, ``/home``,
  ``/root``, ``/tmp``, ``/proc``, no state folder, no other team's files, nothing writable;
* **its own PID, IPC and UTS namespaces**: no other process is visible or can be signalled;
* **no new privileges** (``PR_SET_NO_NEW_PRIVS``) and the death of the child with its host;
* **a seccomp filter** (sandbox/sysfilter.py): no new socket of any family, no ``ptrace``, no
  mount, namespace, keyring, BPF, perf or io_uring call, and no ``execve`` once the child runs;
  each refused with ``EPERM``.

As root, the child still drops to ``nobody`` inside (no user namespace is needed then); as
another user, bwrap makes a user namespace (it needs unprivileged user namespaces).

Without bwrap or libseccomp, team code does not run: the sandbox refuses to start with
:data:`MISSING`, unless the organiser turns the layer off (``robo-comp robots --os-sandbox off``,
``robo-comp league run --os-sandbox off``, or ``ROBO_COMP_OS_SANDBOX=off`` in their environment),
accepting the first wall alone.
"""
from __future__ import annotations

import argparse
import functools
import os
import shutil
import signal
import subprocess
import sys
from dataclasses import dataclass

from robo_comp.errors import UnavailableError
from robo_comp.sandbox import sysfilter

#: Environment variable; ``off`` runs team code without the OS layer (the organiser's choice).
ENV = "ROBO_COMP_OS_SANDBOX"
#: Why team code does not run when the layer is missing (the organiser reads it; one sentence).
MISSING = ("team code runs only inside the OS sandbox (bubblewrap and a seccomp filter), which cannot "
           "start here: {why}; install them (Debian: apt-get install bubblewrap libseccomp2; as a user "
           "other than root bwrap also needs unprivileged user namespaces), or run team code without "
           "this second wall with robo-comp robots --os-sandbox off (robo-comp league run --os-sandbox "
           f"off, or {ENV}=off in their environment; docs/sandbox.md, \"The OS layer\")")


def missing(why: str) -> UnavailableError:
    """The refusal when the layer cannot start here; ``details["why"]`` holds ``why`` alone."""
    return UnavailableError(MISSING.format(why=why), why=why)


def enabled() -> bool:
    """Whether the organiser wants the OS layer (everything but ``ROBO_COMP_OS_SANDBOX=off``)."""
    return os.environ.get(ENV, "").strip().lower() not in ("off", "0", "no", "false")


def choose(setting: str | None) -> None:
    """The organiser's ``--os-sandbox on|off`` (None: leave the environment as it is), for this
    process and every process it starts."""
    if setting is not None:
        os.environ[ENV] = setting


#: What a command that runs team code says at start when the organiser turned the layer off.
OFF = (f"team code runs WITHOUT the OS sandbox here (--os-sandbox off, or {ENV}=off): the policy "
       "and the rlimits are its only walls")


def package_root() -> str:
    """The folder that holds the ``robo_comp`` package (the child imports it from there)."""
    import robo_comp

    return os.path.dirname(os.path.dirname(os.path.abspath(robo_comp.__file__)))


def at_start(command: str, setting: str | None) -> None:
    """At the start of a command that runs team code (``robots``, ``league run``): apply the
    organiser's ``--os-sandbox`` (None: the environment decides) and check the layer here, so
    that the organiser learns now, not from a team's first upload. Says :data:`OFF` on stderr
    when the organiser turned it off; raises :func:`missing`'s refusal (one sentence: how to
    install it or turn it off) when it cannot start, and the command stops."""
    choose(setting)
    if not enabled():
        print(f"robo-comp {command}: {OFF}", file=sys.stderr, flush=True)
        return
    check(package_root())


def add_option(parser: argparse.ArgumentParser) -> None:
    """``--os-sandbox on|off`` for a command that runs team code (``robots``, ``league run``)."""
    parser.add_argument("--os-sandbox", choices=("on", "off"), default=None,
                        help="team code inside the sandbox's OS layer, bubblewrap and a seccomp filter (on: "
                             f"the default), or without it (off: the policy and the rlimits only); sets {ENV} "
                             "for this command and what it starts. Checked at start: where the layer cannot "
                             "run, the command stops and says why (docs/sandbox.md, \"The OS layer\")")


def _binds(pkg_root: str) -> list[str]:
    """Read-only binds: /usr (with the usual links), the Python installation, the virtualenv and
    the package; each once, parents before children."""
    paths = {"/usr", os.path.realpath(sys.base_prefix), os.path.realpath(sys.prefix), sys.prefix,
             os.path.join(pkg_root, "robo_comp")}  # the package only, never the folder around it
    exe = os.path.realpath(sys.executable)
    paths.add(os.path.dirname(os.path.dirname(exe)))  # the interpreter's own prefix
    args: list[str] = []
    kept: list[str] = []
    for p in sorted(paths, key=len):
        if not os.path.isdir(p) or any(p == k or p.startswith(k.rstrip("/") + "/") for k in kept):
            continue
        kept.append(p)
        args += ["--ro-bind", p, p]
    for link in ("lib", "lib64", "bin", "sbin"):
        target = f"/{link}"
        if os.path.islink(target):
            args += ["--symlink", os.readlink(target), target]
        elif os.path.isdir(target) and not target.startswith("/usr"):
            args += ["--ro-bind", target, target]
    return args


def command(pkg_root: str, seccomp_fd: int | None = None) -> list[str]:
    """The bwrap command line that the child's own command follows (after ``--``); with
    ``seccomp_fd``, bwrap reads the start filter (compiled BPF) from that descriptor."""
    bwrap = shutil.which("bwrap")
    if bwrap is None:
        raise missing("bwrap is not installed")
    ns = ["--unshare-net", "--unshare-pid", "--unshare-ipc", "--unshare-uts", "--unshare-cgroup-try"]
    if os.geteuid() != 0:
        ns.append("--unshare-user")  # as root the child drops to nobody itself (a real uid outside)
    seccomp = [] if seccomp_fd is None else ["--seccomp", str(seccomp_fd)]
    return [bwrap, *ns, "--die-with-parent", "--new-session", "--tmpfs", "/", *_binds(pkg_root),
            "--dev", "/dev", "--remount-ro", "/", *seccomp, "--chdir", "/", "--"]


def _filters() -> sysfilter.Programs:
    try:
        return sysfilter.programs()
    except UnavailableError as e:
        raise missing(e.message) from None


def _pipe(data: bytes) -> int:
    """The read end of a pipe holding ``data`` (a filter: far less than a pipe's 64 KiB)."""
    r, w = os.pipe()
    try:
        os.write(w, data)
    finally:
        os.close(w)
    return r


#: Run inside the layer by :func:`check`: the run filter goes on, then a socket and a new program
#: must both be refused by the filters (EPERM), not by anything else.
_SELF_TEST = """import errno, os, socket, sys
sys.path.insert(0, {root!r})
from robo_comp.sandbox.sysfilter import install
install(bytes.fromhex({run!r}), {nr})
for what, attempt in (("socket", socket.socket), ("execve", lambda: os.execv("/", ["/"]))):
    try:
        attempt()
    except OSError as e:
        if e.errno == errno.EPERM:
            continue
    sys.exit("the seccomp filter did not refuse " + what)
"""


@functools.lru_cache(maxsize=4)
def check(pkg_root: str) -> None:
    """Start Python in the OS sandbox once (per process), with both seccomp filters, and see them
    refuse a socket and a new program; raise :class:`UnavailableError` with :data:`MISSING` if
    the layer cannot work here."""
    filters = _filters()
    script = _SELF_TEST.format(root=pkg_root, run=filters.run.hex(), nr=filters.seccomp_nr)
    fd = _pipe(filters.start)
    try:
        r = subprocess.run([*command(pkg_root, fd), os.path.realpath(sys.executable), "-I", "-S", "-c", script],
                           capture_output=True, text=True, timeout=30, stdin=subprocess.DEVNULL,
                           pass_fds=(fd,))
    except (OSError, subprocess.TimeoutExpired) as e:
        raise missing(f"bwrap did not run ({e})") from None
    finally:
        os.close(fd)
    if r.returncode != 0:
        why = (r.stderr.strip().splitlines() or [f"exit code {r.returncode}"])[-1][:200]
        raise missing(f"bwrap failed: {why}")


@dataclass(frozen=True)
class Wall:
    """The OS layer for sandbox children: bwrap's command line and the seccomp filters."""

    pkg_root: str
    filters: sysfilter.Programs | None
    """None only where a test leaves the filter out, to show what it adds."""

    def wrap(self, cmd: list[str]) -> tuple[list[str], int | None]:
        """``cmd`` inside bwrap, and the descriptor bwrap reads the start filter from (the caller
        hands it to the child's process and closes it afterwards; None without a filter)."""
        fd = None if self.filters is None else _pipe(self.filters.start)
        try:
            return [*command(self.pkg_root, fd), *cmd], fd
        except BaseException:
            if fd is not None:
                os.close(fd)
            raise

    def child_filter(self) -> tuple[bytes, int] | None:
        """What the child installs itself before it says ready: the run filter and the
        ``seccomp`` system call's number (None without a filter)."""
        return None if self.filters is None else (self.filters.run, self.filters.seccomp_nr)


def wall(pkg_root: str) -> Wall | None:
    """The OS layer (None when the organiser turned it off); :class:`UnavailableError` with
    :data:`MISSING` when it cannot work here."""
    if not enabled():
        return None
    check(pkg_root)
    return Wall(pkg_root, _filters())


def exit_code(rc: int | None, wrapped: bool) -> int | None:
    """The child's own exit code: bwrap reports a child killed by signal N as ``128 + N``."""
    if wrapped and rc is not None and rc > 128 and rc - 128 in signal.valid_signals():
        return -(rc - 128)
    return rc


def chain(pid: int) -> list[int]:
    """``pid`` and its chain of only children (bwrap → its init → the child), read from
    ``/proc``; ``[pid]`` where there is no such chain."""
    out = [pid]
    for _ in range(4):
        try:
            with open(f"/proc/{pid}/task/{pid}/children") as f:
                kids = f.read().split()
        except OSError:
            break
        if len(kids) != 1:
            break
        pid = int(kids[0])
        out.append(pid)
    return out


def leaf_pid(pid: int) -> int:
    """The process at the end of ``pid``'s chain of only children (bwrap → its init → the
    child); ``pid`` itself where there is no such chain."""
    return chain(pid)[-1]

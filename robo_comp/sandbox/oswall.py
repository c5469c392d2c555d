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
* **no new privileges** (``PR_SET_NO_NEW_PRIVS``) and the death of the child with its host.

As root, the child still drops to ``nobody`` inside (no user namespace is needed then); as
another user, bwrap makes a user namespace (it needs unprivileged user namespaces).

Without bwrap, team code does not run: the sandbox refuses to start with :data:`MISSING`, unless
the organiser turns the layer off with ``ROBO_COMP_OS_SANDBOX=off`` in the environment of the
robot hosts (and of league runs), accepting the first wall alone.
"""
from __future__ import annotations

import functools
import os
import shutil
import signal
import subprocess
import sys

from robo_comp.errors import UnavailableError

#: Environment variable; ``off`` runs team code without the OS layer (the organiser's choice).
ENV = "ROBO_COMP_OS_SANDBOX"
#: Why team code does not run when the layer is missing (the organiser reads it).
MISSING = ("team code runs only inside the OS sandbox (bubblewrap), and it cannot start here: {why}. "
           "Install it (Debian: apt-get install bubblewrap; as a user other than root it also needs "
           "unprivileged user namespaces), or run team code without this second wall by setting "
           f"{ENV}=off in the environment of the robot hosts (docs/sandbox.md, \"The OS layer\")")


def enabled() -> bool:
    """Whether the organiser wants the OS layer (everything but ``ROBO_COMP_OS_SANDBOX=off``)."""
    return os.environ.get(ENV, "").strip().lower() not in ("off", "0", "no", "false")


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


def command(pkg_root: str) -> list[str]:
    """The bwrap command line that the child's own command follows (after ``--``)."""
    bwrap = shutil.which("bwrap")
    if bwrap is None:
        raise UnavailableError(MISSING.format(why="bwrap is not installed"))
    ns = ["--unshare-net", "--unshare-pid", "--unshare-ipc", "--unshare-uts", "--unshare-cgroup-try"]
    if os.geteuid() != 0:
        ns.append("--unshare-user")  # as root the child drops to nobody itself (a real uid outside)
    return [bwrap, *ns, "--die-with-parent", "--new-session", "--tmpfs", "/", *_binds(pkg_root),
            "--dev", "/dev", "--remount-ro", "/", "--chdir", "/", "--"]


@functools.lru_cache(maxsize=4)
def check(pkg_root: str) -> None:
    """Run ``true`` in the OS sandbox once (per process); raise :class:`UnavailableError` with
    :data:`MISSING` if it cannot start here."""
    cmd = command(pkg_root)
    try:
        r = subprocess.run([*cmd, os.path.realpath(sys.executable), "-I", "-S", "-c", "pass"],
                           capture_output=True, text=True, timeout=30, stdin=subprocess.DEVNULL)
    except (OSError, subprocess.TimeoutExpired) as e:
        raise UnavailableError(MISSING.format(why=f"bwrap did not run ({e})")) from None
    if r.returncode != 0:
        why = (r.stderr.strip().splitlines() or [f"exit code {r.returncode}"])[-1][:200]
        raise UnavailableError(MISSING.format(why=f"bwrap failed: {why}"))


def wrap(cmd: list[str], pkg_root: str) -> list[str]:
    """``cmd`` inside the OS sandbox, or ``cmd`` as it is when the organiser turned it off."""
    if not enabled():
        return cmd
    check(pkg_root)
    return [*command(pkg_root), *cmd]


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

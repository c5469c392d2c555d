"""The OS layer's seccomp filter: system calls the sandbox child has no use for are refused.

bubblewrap's namespaces hide the host's network, files and processes (sandbox/oswall.py); the
filter narrows what is left, the kernel itself, so that team code that got past the policy to a
CPython primitive cannot reach the kernel's riskier parts: no new socket of any family (the
child's channel to its host is a socket pair it inherits), no ``ptrace`` or reading another
process's memory, no mounts, namespaces, keyrings, BPF programs, perf events, io_uring, module
or kexec loading, and no new program (``execve``) once the child has started. A refused call
fails with ``EPERM`` ("Operation not permitted"), never a kill, so team code that tries one gets
an ordinary Python error and the sandbox goes on.

The programs are built by libseccomp (Debian's ``libseccomp2``, through ``pyseccomp``) in the
parent and handed over compiled, as BPF:

* **the start filter** goes to bwrap (``--seccomp FD``), which installs it just before it starts
  the child's Python: it holds from the child's first instruction on;
* **the run filter** (no ``execve``) cannot be installed by bwrap, since bwrap then starts the
  child with ``execve``; the child installs it itself, on all of its threads at once
  (``SECCOMP_FILTER_FLAG_TSYNC``), before it says ready (:func:`install`). Filters only add up:
  neither can be lifted by a later one.

The child needs neither libseccomp nor pyseccomp: it loads the compiled program with one system
call (:func:`install`).
"""
from __future__ import annotations

import ctypes
import errno
import functools
from dataclasses import dataclass

from robo_comp.errors import UnavailableError

#: Refused from the child's start on, each with ``EPERM``.
DENIED: tuple[str, ...] = (
    # sockets: the channel to the host is inherited, so the child never makes one
    "socket", "socketpair",
    # other processes: tracing, reading or writing their memory, taking their descriptors
    "ptrace", "process_vm_readv", "process_vm_writev", "pidfd_getfd", "kcmp",
    # the filesystem tree and namespaces: bwrap made them, nobody inside changes them
    "mount", "umount2", "pivot_root", "chroot", "move_mount", "open_tree", "fsopen", "fsconfig",
    "fsmount", "fspick", "mount_setattr", "unshare", "setns", "open_by_handle_at",
    "name_to_handle_at",
    # the kernel's riskier interfaces
    "bpf", "perf_event_open", "userfaultfd", "io_uring_setup", "io_uring_enter",
    "io_uring_register", "keyctl", "add_key", "request_key", "kexec_load", "kexec_file_load",
    "init_module", "finit_module", "delete_module", "reboot", "swapon", "swapoff", "acct",
    "quotactl", "syslog", "uselib", "lookup_dcookie", "iopl", "ioperm", "vhangup",
    # the machine's clock and names
    "settimeofday", "clock_settime", "clock_adjtime", "adjtimex", "sethostname", "setdomainname",
)
#: Refused by the run filter, installed by the child itself once it has started.
DENIED_AFTER_START: tuple[str, ...] = ("execve", "execveat")
#: ``clone`` flags that make a namespace: a ``clone`` with any of them is refused (threads and
#: processes without them are left to the rlimits). ``clone3`` hides its flags in memory the filter
#: cannot read, so it answers ``ENOSYS`` and the C library falls back to ``clone``.
NAMESPACE_FLAGS: tuple[int, ...] = (
    0x00000080,  # CLONE_NEWTIME
    0x00020000,  # CLONE_NEWNS
    0x02000000,  # CLONE_NEWCGROUP
    0x04000000,  # CLONE_NEWUTS
    0x08000000,  # CLONE_NEWIPC
    0x10000000,  # CLONE_NEWUSER
    0x20000000,  # CLONE_NEWPID
    0x40000000,  # CLONE_NEWNET
)

# the seccomp(2) system call's arguments
_SET_MODE_FILTER = 1
_FLAG_TSYNC = 1


@dataclass(frozen=True)
class Programs:
    """Both filters compiled for this machine (BPF), and the number of ``seccomp(2)`` here."""

    start: bytes
    """For bwrap's ``--seccomp``: from the child's first instruction on."""
    run: bytes
    """Installed by the child before it says ready (:func:`install`)."""
    seccomp_nr: int
    """The ``seccomp`` system call's number on this architecture."""


@functools.lru_cache(maxsize=1)
def programs() -> Programs:
    """Build both filters with libseccomp (once per process); :class:`UnavailableError` saying
    why when libseccomp or its binding is missing."""
    import tempfile

    try:
        import pyseccomp as sc
    except ImportError:
        raise UnavailableError("pyseccomp is not installed (pip install pyseccomp)") from None
    except (RuntimeError, OSError) as e:  # the binding found no libseccomp.so.2
        raise UnavailableError(f"libseccomp is not installed ({e})") from None

    def compiled(names: tuple[str, ...], clone_rules: bool) -> bytes:
        f = sc.SyscallFilter(sc.ALLOW)
        # a system call of another ABI (32-bit int 0x80, x32) is refused too, not let through
        f.set_attr(sc.Attr.ACT_BADARCH, sc.ERRNO(errno.EPERM))
        for name in names:
            if sc.resolve_syscall(sc.Arch.NATIVE, name) >= 0:  # some do not exist on every architecture
                f.add_rule(sc.ERRNO(errno.EPERM), name)
        if clone_rules:
            for flag in NAMESPACE_FLAGS:
                f.add_rule(sc.ERRNO(errno.EPERM), "clone", sc.Arg(0, sc.MASKED_EQ, flag, flag))
            f.add_rule(sc.ERRNO(errno.ENOSYS), "clone3")
        with tempfile.TemporaryFile() as out:
            f.export_bpf(out)
            out.seek(0)
            return out.read()

    try:
        nr = sc.resolve_syscall(sc.Arch.NATIVE, "seccomp")
        return Programs(compiled(DENIED, True), compiled(DENIED_AFTER_START, False), nr)
    except OSError as e:
        raise UnavailableError(f"libseccomp could not build the filter ({e})") from None


class _SockFprog(ctypes.Structure):
    _fields_ = [("len", ctypes.c_ushort), ("filter", ctypes.c_void_p)]


def install(program: bytes, seccomp_nr: int) -> None:
    """Install a compiled filter on every thread of this process (the child's side). Needs
    ``PR_SET_NO_NEW_PRIVS`` (bwrap sets it); raises :class:`OSError` if the kernel refuses."""
    if not program or len(program) % 8:
        raise OSError(errno.EINVAL, "not a compiled seccomp program")
    buf = ctypes.create_string_buffer(program, len(program))
    prog = _SockFprog(len(program) // 8, ctypes.cast(buf, ctypes.c_void_p))
    libc = ctypes.CDLL(None, use_errno=True)
    libc.syscall.restype = ctypes.c_long
    rc = libc.syscall(ctypes.c_long(seccomp_nr), ctypes.c_long(_SET_MODE_FILTER),
                      ctypes.c_long(_FLAG_TSYNC), ctypes.byref(prog))
    if rc != 0:  # with TSYNC, a positive answer is a thread that could not take the filter
        err = ctypes.get_errno() if rc < 0 else errno.EBUSY
        raise OSError(err, f"the seccomp filter was not installed: {errno.errorcode.get(err, err)}")

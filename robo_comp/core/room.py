"""Room on the state folder's disk when a core starts: a core restarted on a full disk says
what is full and how much room it needs, then waits for it (or, if asked, exits), instead of
dying with an ``OSError: [Errno 28]`` traceback. Once running, a full disk is a storage fault
the core rides out (see ``docs/reliability.md``)."""
from __future__ import annotations

import errno
import os
import shutil
import time
from collections.abc import Callable
from pathlib import Path

#: Errors that mean "no room" (a full disk, a full quota).
NO_ROOM = frozenset({errno.ENOSPC, errno.EDQUOT})
#: What a starting core needs free: ``core.json``, ``match.json``, tokens and the first records of
#: its event log (the arena, the recovery report) are far smaller; the rest is for the match.
START_ROOM = 1 << 20


def no_room(err: BaseException) -> bool:
    """True for an :class:`OSError` that says the disk (or the quota) is full."""
    return isinstance(err, OSError) and err.errno in NO_ROOM


def _existing(path: Path) -> Path:
    """``path``, or its nearest existing parent (a state folder not made yet)."""
    p = Path(os.path.abspath(path))
    while not p.exists():
        p = p.parent
    return p


def mount_point(path: Path) -> Path:
    """The mount point of the file system that holds ``path`` (its nearest existing folder)."""
    p = _existing(path)
    while not os.path.ismount(p):
        p = p.parent
    return p


def free_bytes(path: Path) -> int:
    """Bytes free for us on the file system of ``path``."""
    return shutil.disk_usage(_existing(path)).free


def _size(n: float) -> str:
    for unit in ("bytes", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} GiB"  # pragma: no cover


def full_disk(state: Path, err: OSError, need: int = START_ROOM) -> str:
    """The sentence for a core that cannot start for want of room."""
    what = f", writing {err.filename}" if err.filename else ""
    return (f"the disk that holds the state folder {state} (the file system mounted on {mount_point(state)}) "
            f"is full ({err.strerror or err}{what}): {_size(free_bytes(state))} free, and the core needs at "
            f"least {_size(need)} to start and record the match. Free space on that disk")


def wait_for_room(state: Path, need: int = START_ROOM, *, poll: float = 1.0,
                  sleep: Callable[[float], None] = time.sleep) -> float:
    """Block until ``need`` bytes are free on the disk of ``state``; return the seconds waited."""
    t0 = time.monotonic()
    while free_bytes(state) < need:
        sleep(poll)
    return time.monotonic() - t0

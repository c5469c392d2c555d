"""Files at rest that belong to the organiser and the teams: folders 0700, files 0600.

Under the usual umask (022) a new file is readable by every user of the machine. The state
folder and the league folder hold every team's source, match logs, pictures and reports, so
whatever writes there goes through these helpers (docs/security.md, "Team data at rest").
"""
from __future__ import annotations

import contextlib
import os
from pathlib import Path

#: Mode of a private folder and of a private file.
DIR_MODE = 0o700
FILE_MODE = 0o600


def private_dir(path: str | Path) -> Path:
    """Make ``path`` (and missing parents) and make it 0700; an existing folder is made 0700 too."""
    p = Path(path)
    p.mkdir(mode=DIR_MODE, parents=True, exist_ok=True)
    with contextlib.suppress(PermissionError):  # a folder of another user: leave it as it is
        os.chmod(p, DIR_MODE)
    return p


def private_file(path: str | Path) -> None:
    """Make an existing file 0600 (a missing one is no error)."""
    with contextlib.suppress(FileNotFoundError, PermissionError):
        os.chmod(path, FILE_MODE)


def write_private(path: str | Path, data: bytes | bytearray | str) -> Path:
    """Write ``data`` to ``path``, a file that is 0600 from its first byte (never readable by
    others in between), replacing what was there."""
    p = Path(path)
    raw = data.encode("utf-8") if isinstance(data, str) else data
    fd = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW, FILE_MODE)
    try:
        os.fchmod(fd, FILE_MODE)
        view = memoryview(raw)
        while view:
            view = view[os.write(fd, view):]
    finally:
        os.close(fd)
    return p

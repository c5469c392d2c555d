"""The append-only event log: every event the core emits, for debugging, replay and recovery
(its format and its readers: :mod:`robo_comp.protocol.logfile`).

File layout (format 2): records framed as marker, length, CRC-32C and a msgpack map (see
:mod:`robo_comp.protocol.logfile`). The first record is a header ``{"format":
"robo_comp-eventlog", "version": 2, "started": t}``; then one record per event ``{"seq": n,
"t": unix_time, "topic": str, "team": str | None, "data": map}``. Records are written in order; the core flushes the buffer at the end of every loop turn,
before any reply of that turn leaves (see docs/protocol.md, "Event log").
"""
from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

from robo_comp.protocol.logfile import FORMAT, FORMAT_VERSION, pack_record


class StorageFault(Exception):
    """The log cannot be written (no space, I/O error, read-only file system, quota); the records
    not yet written stay in memory and :meth:`EventLog.flush` tries them again."""

    def __init__(self, path: Path, err: OSError) -> None:
        super().__init__(f"{path}: {err.strerror or err}")
        self.path = path
        self.errno = err.errno
        self.reason = err.strerror or str(err)


class EventLog:
    """Appends events to ``path``; ``flush()`` hands them to the OS (and fsyncs if asked).

    Records wait in memory until a flush has written them whole; a write that fails (disk
    full, EIO, ...) raises :class:`StorageFault` and keeps every unwritten byte for the next
    flush, so that the file, once the fault clears, holds every record in order."""

    def __init__(self, path: Path, fsync: bool = False, *, seq: int = 0, good_end: int | None = None,
                 legacy: bool = False) -> None:
        """Open ``path`` for appending. After recovery pass the last ``seq`` used (the next event
        gets ``seq + 1``) and the offset ``good_end`` past the last good record: damaged bytes
        beyond it (which hold no record that checks out) are cut off; damage between good
        records stays where it is (the reader skips it). ``legacy``: the log so far is of format
        1, so a format-2 header goes first."""
        self.path = path
        self.fsync = fsync
        path.parent.mkdir(parents=True, exist_ok=True)
        fresh = not path.exists() or path.stat().st_size == 0 or good_end == 0
        if good_end is not None and path.exists() and path.stat().st_size > good_end:
            with open(path, "r+b") as f:
                f.truncate(good_end)
        flags = os.O_WRONLY | os.O_CREAT | os.O_APPEND | (os.O_TRUNC if fresh else 0)
        # the log holds every team's tasks and uploads: the organiser's eyes only
        self._fd = os.open(path, flags, 0o600)
        os.chmod(path, 0o600)
        self._pending = bytearray()  # records appended and not yet written
        self._unsynced = False
        self.seq = seq
        #: The write error that holds records back (None while the log is healthy).
        self.fault: StorageFault | None = None
        if fresh or legacy:
            self._write({"format": FORMAT, "version": FORMAT_VERSION, "started": time.time()})
            try:
                self.flush()
            except StorageFault:
                pass  # kept in memory: the owner's next flush tries again and reports the fault

    def _write(self, obj: dict[str, Any]) -> None:
        self._pending += pack_record(obj)

    def append(self, topic: str, team: str | None, data: dict[str, Any], t: float | None = None) -> int:
        """Append one event; return its sequence number."""
        self.seq += 1
        self._write({"seq": self.seq, "t": time.time() if t is None else t, "topic": topic,
                     "team": team, "data": data})
        return self.seq

    @property
    def unwritten(self) -> int:
        """Bytes of records appended and not yet written to the file."""
        return len(self._pending)

    def flush(self) -> None:
        """Write every waiting record; with ``fsync`` also force them to disk. Raises
        :class:`StorageFault` when the file system refuses (the records wait for the next try)."""
        try:
            while self._pending:
                n = os.write(self._fd, self._pending)
                del self._pending[:n]
                self._unsynced = True
            if self.fsync and self._unsynced:
                os.fsync(self._fd)
            self._unsynced = False
        except OSError as e:
            self.fault = StorageFault(self.path, e)
            raise self.fault from None
        self.fault = None

    def close(self) -> None:
        """Write what waits (as far as the file system lets us) and close the file."""
        try:
            self.flush()
        except StorageFault:
            pass
        os.close(self._fd)

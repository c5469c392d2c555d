"""The append-only event log: every event the core emits, for debugging, replay and recovery.

File layout: records of ``[4-byte big-endian length][msgpack map]``. The first record is a
header ``{"format": "robo_comp-eventlog", "version": 1, "started": t}``; then one record per
event ``{"seq": n, "t": unix_time, "topic": str, "team": str | None, "data": map}``.
Records are written in order; the core flushes the buffer at the end of every loop turn,
before any reply of that turn leaves (see docs/protocol.md, "Event log").
"""
from __future__ import annotations

import os
import struct
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

import msgpack

FORMAT = "robo_comp-eventlog"
FORMAT_VERSION = 1
_LEN = struct.Struct(">I")
MAX_RECORD = 8 << 20


@dataclass(slots=True)
class LogRecord:
    """One event as stored in the log."""

    seq: int
    t: float
    topic: str
    team: str | None
    data: dict[str, Any]


class EventLog:
    """Appends events to ``path``; ``flush()`` pushes them to the OS (and fsyncs if asked)."""

    def __init__(self, path: Path, fsync: bool = False, *, seq: int = 0, good_end: int | None = None) -> None:
        """Open ``path`` for appending. After recovery pass the last ``seq`` and the offset
        ``good_end`` past the last good record: a damaged tail beyond it is cut off."""
        self.path = path
        self.fsync = fsync
        path.parent.mkdir(parents=True, exist_ok=True)
        fresh = not path.exists() or path.stat().st_size == 0 or good_end == 0
        if good_end is not None and path.exists() and path.stat().st_size > good_end:
            with open(path, "r+b") as f:
                f.truncate(good_end)
        self._f: BinaryIO = open(path, "wb" if fresh else "ab", buffering=1 << 16)
        os.chmod(path, 0o600)  # the log holds every team's tasks and uploads: the organiser's eyes only
        self.seq = seq
        self._dirty = False
        if fresh:
            self._write({"format": FORMAT, "version": FORMAT_VERSION, "started": time.time()})
            self.flush()

    def _write(self, obj: dict[str, Any]) -> None:
        blob = msgpack.packb(obj, use_bin_type=True)
        self._f.write(_LEN.pack(len(blob)))
        self._f.write(blob)
        self._dirty = True

    def append(self, topic: str, team: str | None, data: dict[str, Any], t: float | None = None) -> int:
        """Append one event; return its sequence number."""
        self.seq += 1
        self._write({"seq": self.seq, "t": time.time() if t is None else t, "topic": topic,
                     "team": team, "data": data})
        return self.seq

    def flush(self) -> None:
        """Hand buffered records to the OS; with ``fsync`` also force them to disk."""
        if self._dirty:
            self._f.flush()
            if self.fsync:
                os.fsync(self._f.fileno())
            self._dirty = False

    def close(self) -> None:
        """Flush and close the file."""
        self.flush()
        self._f.close()


class LogCorrupt(Exception):
    """Raised by :func:`read_log` in strict mode when the log's tail is damaged."""

    def __init__(self, offset: int, reason: str) -> None:
        super().__init__(f"event log damaged at byte {offset}: {reason}")
        self.offset = offset
        self.reason = reason


class LogReader:
    """Iterates over a log's records; afterwards ``good_end`` is the byte offset just past the
    last good record and ``damage`` says what was wrong past it (None for a clean log)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.good_end = 0
        self.damage: LogCorrupt | None = None
        self.last_seq = 0

    def __iter__(self) -> Iterator[LogRecord]:
        with open(self.path, "rb") as f:
            data = f.read()
        view = memoryview(data)  # slices without copying
        off = 0
        first = True
        unpack = msgpack.unpackb
        while off < len(data):
            if off + 4 > len(data):
                self.damage = LogCorrupt(off, "truncated length prefix")
                return
            (n,) = _LEN.unpack_from(data, off)
            if n > MAX_RECORD or off + 4 + n > len(data):
                self.damage = LogCorrupt(off, "truncated record")
                return
            try:
                obj = unpack(view[off + 4: off + 4 + n], raw=False)
            except Exception:
                self.damage = LogCorrupt(off, "record is not valid msgpack")
                return
            if first:
                if type(obj) is not dict or obj.get("format") != FORMAT:
                    self.damage = LogCorrupt(off, "not a robo_comp event log")
                    return
                if obj.get("version") != FORMAT_VERSION:
                    self.damage = LogCorrupt(off, f"log format version {obj.get('version')} is not supported")
                    return
                first = False
            else:
                try:
                    rec = LogRecord(obj["seq"], obj["t"], obj["topic"], obj.get("team"), obj["data"])
                except (KeyError, TypeError):
                    self.damage = LogCorrupt(off, "record lacks seq/t/topic/data")
                    return
                self.last_seq = rec.seq
                yield rec
            off += 4 + n
            self.good_end = off


def read_log(path: Path, strict: bool = True) -> Iterator[LogRecord]:
    """Yield the events of a log in order.

    A truncated or corrupt tail raises :class:`LogCorrupt` in strict mode, after every good
    record before it was yielded; otherwise reading stops quietly at the damage.
    """
    reader = LogReader(path)
    yield from reader
    if strict and reader.damage is not None:
        raise reader.damage

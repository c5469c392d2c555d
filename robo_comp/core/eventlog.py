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

    def __init__(self, path: Path, fsync: bool = False) -> None:
        self.path = path
        self.fsync = fsync
        path.parent.mkdir(parents=True, exist_ok=True)
        fresh = not path.exists() or path.stat().st_size == 0
        self._f: BinaryIO = open(path, "ab", buffering=1 << 16)
        self.seq = 0
        self._dirty = False
        if fresh:
            self._write({"format": FORMAT, "version": FORMAT_VERSION, "started": time.time()})
        else:
            for rec in read_log(path, strict=False):
                self.seq = rec.seq

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


def read_log(path: Path, strict: bool = True) -> Iterator[LogRecord]:
    """Yield the events of a log in order.

    A truncated or corrupt tail raises :class:`LogCorrupt` in strict mode, after every good
    record before it was yielded; otherwise reading stops quietly at the damage.
    """
    with open(path, "rb") as f:
        data = f.read()
    off = 0
    first = True
    while off < len(data):
        if off + 4 > len(data):
            return _damage(strict, off, "truncated length prefix")
        (n,) = _LEN.unpack_from(data, off)
        if n > MAX_RECORD or off + 4 + n > len(data):
            return _damage(strict, off, "truncated record")
        try:
            obj = msgpack.unpackb(data[off + 4: off + 4 + n], raw=False)
        except Exception:
            return _damage(strict, off, "record is not valid msgpack")
        if first:
            if type(obj) is not dict or obj.get("format") != FORMAT:
                return _damage(strict, off, "not a robo_comp event log")
            if obj.get("version") != FORMAT_VERSION:
                return _damage(strict, off, f"log format version {obj.get('version')} is not supported")
            first = False
        else:
            try:
                yield LogRecord(obj["seq"], obj["t"], obj["topic"], obj.get("team"), obj["data"])
            except (KeyError, TypeError):
                return _damage(strict, off, "record lacks seq/t/topic/data")
        off += 4 + n


def _damage(strict: bool, off: int, reason: str) -> None:
    if strict:
        raise LogCorrupt(off, reason)

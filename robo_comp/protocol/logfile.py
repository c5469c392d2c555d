"""The event log's file format, and reading it: what the core writes, and what replays, walls,
web views and the bench read.

File layout: records of ``[4-byte big-endian length][msgpack map]``. The first record is a
header ``{"format": "robo_comp-eventlog", "version": 1, "started": t}``; then one record per
event ``{"seq": n, "t": unix_time, "topic": str, "team": str | None, "data": map}``.
Records are written in order; the core flushes the buffer at the end of every loop turn,
before any reply of that turn leaves (see docs/protocol.md, "Event log").
"""
from __future__ import annotations

import os
import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgpack

from robo_comp.errors import FieldError

FORMAT = "robo_comp-eventlog"
FORMAT_VERSION = 1
#: The length prefix of every record.
RECORD_LENGTH = struct.Struct(">I")
MAX_RECORD = 8 << 20


@dataclass(slots=True)
class LogRecord:
    """One event as stored in the log."""

    seq: int
    t: float
    topic: str
    team: str | None
    data: dict[str, Any]


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
            (n,) = RECORD_LENGTH.unpack_from(data, off)
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


def write_log(path: Path, events: Iterable[tuple[str, str | None, dict[str, Any], float]],
              started: float = 0.0) -> Path:
    """Write a whole log at once: the header (``started``) and one record per
    ``(topic, team, data, t)``, numbered from 1. Used by the bench and the league, whose matches
    run on a simulated clock (so equal matches give byte-identical files); the core appends
    with :class:`robo_comp.core.eventlog.EventLog` instead."""
    out = bytearray()

    def put(obj: dict[str, Any]) -> None:
        blob = msgpack.packb(obj, use_bin_type=True)
        out.extend(RECORD_LENGTH.pack(len(blob)))
        out.extend(blob)

    put({"format": FORMAT, "version": FORMAT_VERSION, "started": started})
    for seq, (topic, team, data, t) in enumerate(events, start=1):
        put({"seq": seq, "t": t, "topic": topic, "team": team, "data": data})
    path.parent.mkdir(parents=True, exist_ok=True)
    # 0600 from the first byte, as the core's own log: a match log holds the teams' tasks and finds
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as f:
        os.fchmod(fd, 0o600)
        f.write(out)
    return path


def read_log(path: Path, strict: bool = True) -> Iterator[LogRecord]:
    """Yield the events of a log in order.

    A truncated or corrupt tail raises :class:`LogCorrupt` in strict mode, after every good
    record before it was yielded; otherwise reading stops quietly at the damage.
    """
    reader = LogReader(path)
    yield from reader
    if strict and reader.damage is not None:
        raise reader.damage


def read_recording(log: Path) -> tuple[list[LogRecord], dict[str, Any]]:
    """The records of ``log`` and its ``core.started`` data (which carries the arena)."""
    if not log.is_file():
        raise FieldError(f"{log}: no such event log (a core writes STATE/events.log)")
    try:
        records = list(read_log(log, strict=False))
    except OSError as e:
        raise FieldError(f"cannot read the event log {log}: {e.strerror}") from None
    started = next((r.data for r in records if r.topic == "core.started" and "arena" in r.data), None)
    if started is None:
        raise FieldError(f"{log}: no core.started record with the arena; is this a robo_comp event log?")
    return records, started

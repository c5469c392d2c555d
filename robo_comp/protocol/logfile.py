"""The event log's file format, and reading it: what the core writes, and what replays, walls,
web views, the league and the bench read (this module is the one reader).

Format 2 (written since issue 32): every record is framed as

    ``MAGIC`` (4 bytes ``d3 52 43 4c``) · CRC-32C (4-byte big-endian, of the length bytes and the
    payload, which follow it) · length (4-byte big-endian) · payload (a msgpack map)

The first record is a header ``{"format": "robo_comp-eventlog", "version": 2, "started": t}``;
then one record per event ``{"seq": n, "t": unix_time, "topic": str, "team": str | None,
"data": map}``. The checksum makes every record prove itself: a changed byte anywhere in a
record (marker, length, checksum or payload) makes that record fail its check, and the reader
*resynchronises* at the next marker whose record checks out, so one damaged record costs that
record only. What was lost is reported by sequence number (the gap between the good records
around the damage) and, where the damaged bytes still say it, by topic.

Format 1 (before issue 32) framed records as ``[4-byte length][msgpack map]`` without a
checksum. Such a log is still read (and :attr:`LogReader.legacy` says how many of its records
were read without a check); a core that recovers one appends format-2 records after them,
starting with a format-2 header (the marker, read as a format-1 length, is larger than any
record, so the two never mix up).

Records are written in order; the core flushes the buffer at the end of every loop turn,
before any reply of that turn leaves (see docs/protocol.md, "Event log").
"""
from __future__ import annotations

import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgpack
from crc32c import crc32c

from robo_comp.errors import FieldError
from robo_comp.private_files import write_private

FORMAT = "robo_comp-eventlog"
#: The format the core writes.
FORMAT_VERSION = 2
#: The format before checksums, still read.
LEGACY_VERSION = 1
#: Every format-2 record starts with these bytes (read as a format-1 length they exceed MAX_RECORD).
MAGIC = b"\xd3RCL"
#: A format-2 record's head: marker, CRC-32C of the length bytes and the payload, payload length.
RECORD_HEAD = struct.Struct(">4sII")
#: The length prefix of a format-1 record.
RECORD_LENGTH = struct.Struct(">I")
MAX_RECORD = 8 << 20
#: No event record is shorter than this (head and the smallest ``{seq, t, topic, team, data}``):
#: damaged bytes at the end of a log can have held at most ``len // MIN_RECORD`` records.
MIN_RECORD = 40


def frame(payload: bytes) -> bytes:
    """One format-2 record around a packed msgpack ``payload``."""
    n = RECORD_LENGTH.pack(len(payload))
    return MAGIC + RECORD_LENGTH.pack(crc32c(payload, crc32c(n))) + n + payload


def pack_record(obj: dict[str, Any]) -> bytes:
    """A log record (header or event) as format-2 bytes."""
    return frame(msgpack.packb(obj, use_bin_type=True))


@dataclass(slots=True)
class LogRecord:
    """One event as stored in the log."""

    seq: int
    t: float
    topic: str
    team: str | None
    data: dict[str, Any]


class LogCorrupt(Exception):
    """Raised by :func:`read_log` in strict mode when the log is damaged (after every good
    record was yielded)."""

    def __init__(self, offset: int, reason: str) -> None:
        super().__init__(f"event log damaged at byte {offset}: {reason}")
        self.offset = offset
        self.reason = reason


@dataclass
class Damage:
    """One damaged stretch of a log: bytes ``[start, end)`` that hold no record that checks out.

    ``lost`` are the sequence numbers of the events that were there (the gap between the good
    records around it; for damage at the end of the log, what the bytes still say, if anything);
    ``topics`` maps those the damaged bytes still name to their topic (unverified: the bytes
    failed their check). ``tail`` is True when no good record follows; then ``lost`` counts a
    record for each marker in the damaged bytes (at least one), numbered on from the last good
    record (a record cut short by a crash was never acknowledged)."""

    start: int
    end: int
    reason: str
    lost: list[int] = field(default_factory=list)
    topics: dict[int, str] = field(default_factory=dict)
    tail: bool = False

    def describe(self) -> str:
        """A sentence for the referee."""
        size = self.end - self.start
        where = f"bytes {self.start}-{self.end} ({size} bytes{', the end of the log' if self.tail else ''})"
        if self.lost:
            named = ", ".join(f"{s} (probably {self.topics[s]})" if s in self.topics else str(s) for s in self.lost[:20])
            more = f" and {len(self.lost) - 20} more" if len(self.lost) > 20 else ""
            what = f"lost event{'s' if len(self.lost) > 1 else ''} {named}{more}"
        else:
            what = "no event was lost (the damage lies between records)"
        if self.tail and self.reason.startswith("truncated"):
            what += " (a write cut short by a crash: not acknowledged to anyone)"
        return f"{where}: {self.reason}; {what}"

    def to_dict(self) -> dict[str, Any]:
        """Plain data (part of the ``core.recovered`` event)."""
        return {"start": self.start, "end": self.end, "reason": self.reason, "tail": self.tail,
                "lost": [{"seq": s, "topic": self.topics.get(s)} for s in self.lost]}


def _peek(buf: bytes | memoryview) -> dict[str, Any]:
    """What damaged bytes still say of the record they held: the keys of its map that decode,
    in order, until the bytes stop making sense (never trusted: for the report only)."""
    u = msgpack.Unpacker(raw=False, max_buffer_size=MAX_RECORD + 64)
    u.feed(bytes(buf[:4096]))
    out: dict[str, Any] = {}
    try:
        for _ in range(u.read_map_header()):
            k = u.unpack()
            if k == "data":
                break
            out[k] = u.unpack()
    except Exception:
        pass
    return out


class LogReader:
    """Iterates over a log's good records, resynchronising after damage.

    Afterwards: ``good_end`` is the byte offset just past the last good record (damage after it
    is at the end of the log); ``damages`` lists every damaged stretch (empty for a clean log) and
    ``damage`` the first as a :class:`LogCorrupt`; ``last_seq`` is the highest sequence number
    of a good record; ``next_seq`` the lowest number that no record, good or damaged, can have
    used; ``legacy`` how many records were read in format 1 (without a checksum); ``version``
    the format of the log's last header."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.good_end = 0
        self.damages: list[Damage] = []
        self.last_seq = 0
        self.next_seq = 1
        self.legacy = 0
        self.version: int | None = None

    @property
    def damage(self) -> LogCorrupt | None:
        """The first damage, as an exception (None for a clean log)."""
        if not self.damages:
            return None
        d = self.damages[0]
        return LogCorrupt(d.start, d.reason)

    def __iter__(self) -> Iterator[LogRecord]:
        with open(self.path, "rb") as f:
            data = f.read()
        view = memoryview(data)  # slices without copying
        size = len(data)
        off = 0
        unpack = msgpack.unpackb
        head = RECORD_HEAD.unpack_from
        length = RECORD_LENGTH.unpack_from
        bad: tuple[int, str] | None = None  # (start, reason) of the damage being skipped
        prev_seq = 0  # the last good record's seq before the damage being skipped
        legacy = False
        if size >= 4 and data[:4] != MAGIC:  # format 1? (its header is its first record)
            (n,) = length(data, 0)
            try:
                obj = unpack(view[4:4 + n], raw=False) if n <= MAX_RECORD and 4 + n <= size else None
            except Exception:
                obj = None
            legacy = type(obj) is dict and obj.get("format") == FORMAT and obj.get("version") == LEGACY_VERSION
        while off < size:
            if legacy:
                # format 1: no checksum, no marker; its damage can only be found where msgpack fails
                if data[off:off + 4] == MAGIC:
                    legacy = False  # format-2 records follow (a core recovered this log and went on)
                    continue
                reason = None
                if off + 4 > size:
                    reason = "truncated length prefix"
                else:
                    (n,) = length(data, off)
                    if n > MAX_RECORD or off + 4 + n > size:
                        reason = "truncated record"
                if reason is None:
                    try:
                        obj = unpack(view[off + 4: off + 4 + n], raw=False)
                    except Exception:
                        reason = "record is not valid msgpack"
                if reason is not None:
                    legacy = False
                    bad = (off, reason + " (format 1, without checksums)")
                    prev_seq = self.last_seq
                    nxt = data.find(MAGIC, off + 1)
                    off = size if nxt < 0 else nxt
                    continue
                rec = self._record(obj, off)
                if rec is None:
                    self.version = LEGACY_VERSION
                elif isinstance(rec, str):
                    legacy = False
                    bad = (off, rec)
                    prev_seq = self.last_seq
                    nxt = data.find(MAGIC, off + 1)
                    off = size if nxt < 0 else nxt
                    continue
                else:
                    self.legacy += 1
                    yield rec
                off += 4 + n
                self.good_end = off
                continue
            # format 2
            reason = None
            if off + RECORD_HEAD.size > size:
                reason = "truncated record head"
            else:
                magic, crc, n = head(data, off)
                end = off + RECORD_HEAD.size + n
                if magic != MAGIC:
                    reason = "no record marker"
                elif n > MAX_RECORD or end > size:
                    reason = "truncated record" if n <= MAX_RECORD else "impossible record length"
                elif crc32c(view[off + 8:end]) != crc:
                    reason = "checksum mismatch"
            if reason is None:
                try:
                    obj = unpack(view[off + RECORD_HEAD.size:end], raw=False)
                except Exception:
                    reason = "record is not valid msgpack (written so)"
            rec = None
            if reason is not None:
                pass
            elif bad is None and self.version is not None and type(obj) is dict and "seq" in obj:
                # the common case, inline: an event record after a header, no damage pending
                try:
                    rec = LogRecord(obj["seq"], obj["t"], obj["topic"], obj.get("team"), obj["data"])
                except (KeyError, TypeError):
                    rec = "record lacks seq/t/topic/data"
                else:
                    if rec.seq > self.last_seq:
                        self.last_seq = rec.seq
                    yield rec
                    off = end
                    self.good_end = off
                    continue
            else:
                rec = self._record(obj, off)
            if isinstance(rec, str):
                reason, rec = rec, None
            if reason is not None:
                if bad is None:
                    bad = (off, reason)
                    prev_seq = self.last_seq
                nxt = data.find(MAGIC, off + 1)
                off = size if nxt < 0 else nxt
                continue
            if bad is not None:  # a good record after damage: the damage ends here
                self._damaged(view, bad, off, prev_seq, rec.seq if rec is not None else None, tail=False)
                bad = None
            if rec is None:
                self.version = FORMAT_VERSION
            else:
                yield rec
            off = end
            self.good_end = off
        if bad is not None:
            self._damaged(view, bad, size, prev_seq, None, tail=True)
        if self.version is None and not self.damages and size:
            self.damages.append(Damage(0, size, "not a robo_comp event log", tail=True))
        self.next_seq = max(self.next_seq, self.last_seq + 1)

    def _record(self, obj: Any, off: int) -> LogRecord | str | None:
        """The event in a decoded record (None for a header; a reason for something else)."""
        if type(obj) is not dict:
            return "record is not a map"
        if "format" in obj and "seq" not in obj:
            if obj.get("format") != FORMAT:
                return "not a robo_comp event log"
            if obj.get("version") not in (LEGACY_VERSION, FORMAT_VERSION):
                return f"log format version {obj.get('version')} is not supported"
            return None
        try:
            rec = LogRecord(obj["seq"], obj["t"], obj["topic"], obj.get("team"), obj["data"])
        except (KeyError, TypeError):
            return "record lacks seq/t/topic/data"
        if self.version is None:  # the header was damaged (reported as such)
            self.version = FORMAT_VERSION
        if rec.seq > self.last_seq:
            self.last_seq = rec.seq
        return rec

    def _damaged(self, view: memoryview, bad: tuple[int, str], end: int, prev: int, after: int | None,
                 tail: bool) -> None:
        """Record the damage ``bad`` (start, reason) that ends at ``end``, between the good records
        of seq ``prev`` and ``after`` (None: no event record follows)."""
        start, reason = bad
        d = Damage(start, end, reason, tail=tail)
        said = _peek(view[start + RECORD_HEAD.size:end]) if end - start > RECORD_HEAD.size else {}
        if not said:  # a format-1 record, or a marker lost with its head
            said = _peek(view[start + 4:end]) if end - start > 4 else {}
        if "format" in said:
            d.reason += " (the log's header)"
        seq, topic = said.get("seq"), said.get("topic")
        if after is not None:
            d.lost = list(range(prev + 1, after))
            if type(seq) is int and prev < seq < after and isinstance(topic, str):
                d.topics[seq] = topic
        else:
            # at the end nothing follows to bound it: every record there starts with the marker
            # (one whose marker is damaged counts as one), numbered on from the last good one
            count = max(1, bytes(view[start:end]).count(MAGIC))
            d.lost = list(range(prev + 1, prev + 1 + count))
            if count == 1 and seq == prev + 1 and isinstance(topic, str):
                d.topics[seq] = topic
            # and no number the damaged bytes could have held is ever given again
            self.next_seq = max(self.next_seq, prev + 1 + max(count, (end - start) // MIN_RECORD + 1))
        self.damages.append(d)


def write_log(path: Path, events: Iterable[tuple[str, str | None, dict[str, Any], float]],
              started: float = 0.0) -> Path:
    """Write a whole log at once: the header (``started``) and one record per
    ``(topic, team, data, t)``, numbered from 1. Used by the bench and the league, whose matches
    run on a simulated clock (so equal matches give byte-identical files); the core appends
    with :class:`robo_comp.core.eventlog.EventLog` instead."""
    out = bytearray()

    def put(obj: dict[str, Any]) -> None:
        out.extend(pack_record(obj))

    put({"format": FORMAT, "version": FORMAT_VERSION, "started": started})
    for seq, (topic, team, data, t) in enumerate(events, start=1):
        put({"seq": seq, "t": t, "topic": topic, "team": team, "data": data})
    path.parent.mkdir(parents=True, exist_ok=True)
    # 0600 from the first byte, as the core's own log: a match log holds the teams' tasks and finds
    return write_private(path, out)


def read_log(path: Path, strict: bool = True) -> Iterator[LogRecord]:
    """Yield the events of a log in order.

    Damaged records are skipped (the reader resynchronises at the next good record); in strict
    mode a damaged log raises :class:`LogCorrupt` for its first damage after every good record
    was yielded.
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

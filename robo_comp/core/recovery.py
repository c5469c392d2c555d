"""Recovery: rebuild the core's match from its event log after a crash (even ``kill -9``).

The log holds every state change (see ``docs/protocol.md``, "Event log"): the match's own fold
(:class:`robo_comp.match.restore.Restorer`) replays it into a freshly made match, restoring robots
and their tags, advertised tasks, current/pending/queued/done tasks, the match phase and clock,
score changes, disqualifications, pictures (evidence) and finds. Robots come back as ``lost``
until their hosts re-register (with the same robot ids, so the same tags). This module reads the
log file and says what it found.
Every record carries a checksum: a damaged record costs that record only. Recovery skips it,
keeps every good record after it, and reports exactly which sequence numbers were lost (with
their topics where the damaged bytes still say them) in the ``core.recovered`` event. Damaged
bytes at the very end (an unfinished write) are cut off, with a copy kept; the sequence numbers
they could have held are never used again. A log of format 1 (without checksums) is read and
said so.
"""
from __future__ import annotations

import logging
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from robo_comp.match.model import Match
from robo_comp.match.restore import Restorer
from robo_comp.protocol.logfile import FORMAT_VERSION, LEGACY_VERSION, Damage, LogReader

log = logging.getLogger("robo_comp.core")


@dataclass
class RecoveryReport:
    """What recovery found: how many events, how long it took, and any damage."""

    events: int
    seq: int
    good_end: int
    seconds: float
    damage: str | None = None
    damaged_copy: str | None = None
    #: Every damaged stretch of the log (empty for a clean log).
    damages: list[Damage] = field(default_factory=list)
    #: Records read in format 1 (no checksums); 0 for a format-2 log.
    legacy: int = 0
    #: The log's last header is of format 1: what is appended needs a format-2 header first.
    legacy_tail: bool = False
    #: How the match clock was set (match time as recorded; the outage rule).
    clock: str = ""

    @property
    def lost(self) -> list[int]:
        """Sequence numbers of the events the damage cost."""
        return [s for d in self.damages for s in d.lost]

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (the ``core.recovered`` event)."""
        return {"events": self.events, "seq": self.seq, "seconds": round(self.seconds, 4),
                "damage": self.damage, "damaged_copy": self.damaged_copy,
                "damages": [d.to_dict() for d in self.damages], "lost": self.lost,
                "legacy_records": self.legacy, "clock": self.clock}


def recover(match: Match, path: Path) -> RecoveryReport:
    """Replay ``path`` into ``match``: every good record, skipping damaged ones (see the module
    docstring). ``seq`` of the report is the last sequence number that may have been used (the
    next event gets ``seq + 1``); ``good_end`` where damaged bytes at the end begin."""
    t0 = time.perf_counter()
    reader = LogReader(path)
    rep = Restorer(match)
    n = 0
    for rec in reader:
        rep.apply(rec.topic, rec.team, rec.data, rec.t)
        n += 1
    rep.finish(outage=True)
    rep.hosts_gone()
    report = RecoveryReport(n, reader.next_seq - 1, reader.good_end, time.perf_counter() - t0,
                            damages=reader.damages, legacy=reader.legacy,
                            legacy_tail=reader.version == LEGACY_VERSION, clock=rep.clock_note)
    if reader.legacy:
        log.warning("event log: %d records are of the previous format (1, without checksums); they were "
                    "read without a check, and new records are written in format %d after them",
                    reader.legacy, FORMAT_VERSION)
    if reader.damages:
        said = [d.describe() for d in reader.damages]
        cut = path.stat().st_size - reader.good_end
        if cut > 0:
            copy = path.with_name(f"{path.name}.damaged-{int(time.time())}")
            try:
                shutil.copyfile(path, copy)
                report.damaged_copy = str(copy)
                kept = f"a copy of the log is in {copy}"
            except OSError as e:  # a full disk: the damaged bytes are cut all the same (nothing good is in them)
                copy.unlink(missing_ok=True)
                kept = f"no copy could be kept: {e.strerror}"
            said.append(f"the {cut} damaged bytes at the end were cut off ({kept})")
        lost = report.lost
        report.damage = (f"the event log is damaged in {len(reader.damages)} place"
                         f"{'s' if len(reader.damages) > 1 else ''}; {len(lost)} event"
                         f"{'s' if len(lost) != 1 else ''} lost, every other record recovered: " + "; ".join(said))
        log.warning("event log: %s", report.damage)
    return report

"""The referee console's line about the core itself: the outage rule of the match clock and what
the core recovered from its event log when it (re)started (issue 32).

Lost events are told in words and with a ``⚠`` mark, never by colour alone; the line turns into
a banner (class ``-lost``) while the report names any.
"""
from __future__ import annotations

from typing import Any

from rich.text import Text
from textual.widgets import Static

from robo_comp.tui.model import ConsoleModel, lost_events

#: The outage rules in the line's few words (the report and the form say them in full).
SHORT_RULE = {"pause": "clock pauses", "count": "clock counts it"}
#: How many lost events the line names before "and N more" (the report, ``r``, names them all).
NAMED = 4


def lost_summary(recovered: dict[str, Any] | None, named: int = NAMED) -> str:
    """``2 events lost: 120 score.change, 131 (topic unreadable)`` ("" when none was lost)."""
    lost = lost_events(recovered)
    if not lost:
        return ""
    words = [f"{s} {t}" if t else f"{s} (topic unreadable)" for s, t in lost[:named]]
    more = f" and {len(lost) - named} more" if len(lost) > named else ""
    return f"{len(lost)} event{'s' if len(lost) != 1 else ''} lost: {', '.join(words)}{more}"


def recovery_words(model: ConsoleModel) -> str:
    """What the core recovered, in one phrase (no mark: :class:`CoreLine` adds it)."""
    rec = model.recovered
    if not model.recovery_known:
        return "log: not reported by this core"
    if rec is None:
        return "log: started on an empty folder"
    lost = lost_summary(rec)
    if lost:
        return f"LOG DAMAGED, {lost}"
    old = f" ({rec['legacy_records']} of the old format, unchecked)" if rec.get("legacy_records") else ""
    if rec.get("damage"):
        return f"log damaged between records, no event lost; {rec.get('events', 0):,} events recovered{old}"
    return f"log OK, {rec.get('events', 0):,} events{old}"


class CoreLine(Static):
    """``log OK, 532 events (r) · outage: clock pauses (o)``: ``r`` opens
    the recovery report, ``o`` changes the outage rule."""

    DEFAULT_CSS = """
    CoreLine { height: auto; padding: 0 1; color: $text-muted; }
    CoreLine.-lost { background: $error; color: $text; text-style: bold; }
    CoreLine.-damaged { color: $warning; }
    """

    def __init__(self, model: ConsoleModel, id: str | None = None) -> None:
        super().__init__("", id=id)
        self.model = model

    def update_from(self, model: ConsoleModel) -> None:
        """Redraw from the model."""
        rec = model.recovered
        lost = bool(lost_events(rec))
        self.set_class(lost, "-lost")
        self.set_class(bool(rec and rec.get("damage")) and not lost, "-damaged")
        outage = f"outage: {SHORT_RULE.get(model.outage or '', 'rule not reported')}"
        t = Text()
        if lost:
            t.append("⚠ ")
        t.append(recovery_words(model))
        t.append(" (r)" if rec else "")
        t.append("\n" if lost else " · ")  # a banner: the loss on a line of its own
        t.append(f"{outage} (o)")
        self.update(t)

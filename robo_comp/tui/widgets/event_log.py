"""The event log pane: every event as a readable line, with an optional filter (text and team)."""
from __future__ import annotations

import time
from collections.abc import Iterable

from rich.text import Text
from textual.widgets import RichLog

from robo_comp.tui.model import LogEntry, describe_event

TOPIC_STYLE = {
    "robot.lost": "bold red", "robot.stopped": "bold yellow", "task.done": "green", "refused": "red",
    "penalty": "bold magenta", "disqualified": "bold magenta", "broadcast": "bold cyan",
    "match.phase": "bold", "upload.done": "cyan", "upload.pending": "cyan",
}


class EventLog(RichLog):
    """A scrolling log of events; :meth:`set_filter` shows only lines matching text and team."""

    DEFAULT_CSS = """
    EventLog { height: 1fr; }
    """

    def __init__(self, id: str | None = None) -> None:
        super().__init__(id=id, wrap=True, markup=False, highlight=False, max_lines=2000)
        self.border_title = "Events"
        self.text_filter = ""
        self.team_filter: str | None = None

    def matches(self, e: LogEntry) -> bool:
        """Does ``e`` pass the current filter?"""
        if self.team_filter and e.team not in (self.team_filter, "*"):
            return False
        if self.text_filter:
            needle = self.text_filter.lower()
            return needle in e.topic or needle in describe_event(e).lower()
        return True

    def line(self, e: LogEntry) -> Text:
        """The log line of ``e``."""
        t = Text(no_wrap=False)
        t.append(time.strftime("%H:%M:%S ", time.localtime(e.t)), style="dim")
        ok = e.data.get("ok")
        style = TOPIC_STYLE.get(e.topic, "")
        if e.topic == "task.done" and not ok:
            style = "yellow"
        t.append(describe_event(e), style=style)
        return t

    def add(self, e: LogEntry) -> None:
        """Append one entry if it passes the filter."""
        if self.matches(e):
            self.write(self.line(e))

    def set_filter(self, entries: Iterable[LogEntry], text: str = "", team: str | None = None) -> None:
        """Change the filter and redraw from ``entries``."""
        self.text_filter = text.strip()
        self.team_filter = team or None
        self.clear()
        for e in entries:
            self.add(e)
        shown = [f"“{self.text_filter}”"] if self.text_filter else []
        shown += [f"team {self.team_filter}"] if self.team_filter else []
        self.border_title = "Events" + (f" · {' · '.join(shown)}" if shown else "")

"""The recovery report in the referee console (key ``r``): what the core read back from its event
log when it started, every damaged stretch, every lost event with its topic, and the clock."""
from __future__ import annotations

from typing import Any

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Button, Static

from robo_comp.tui.model import OUTAGE_WORDS, lost_events


def report_text(recovered: dict[str, Any] | None, known: bool, outage: str | None) -> Text:
    """The report as text (also what ``ctl recovery`` prints, with the lost events listed)."""
    t = Text()
    if not known:
        t.append("This core does not report what it recovered (an older core).")
    elif recovered is None:
        t.append("The core started on an empty state folder: nothing was recovered.")
    else:
        t.append(f"The core recovered {recovered.get('events', 0):,} events in {recovered.get('seconds', 0):.2f} s")
        if recovered.get("legacy_records"):
            t.append(f"; {recovered['legacy_records']:,} of them of the previous log format (no checksums)")
        t.append(".\n")
        lost = lost_events(recovered)
        if lost:
            t.append(f"\n⚠ {len(lost)} event{'s' if len(lost) != 1 else ''} LOST from the log:\n", style="bold")
            for seq, topic in lost:
                t.append(f"  seq {seq:>7}  {topic or '(the topic could not be read)'}\n")
        if recovered.get("damage"):
            t.append(f"\n{recovered['damage']}\n")
        else:
            t.append("\nThe event log is undamaged.\n")
        if recovered.get("damaged_copy"):
            t.append(f"\nA copy of the damaged log: {recovered['damaged_copy']}\n")
        if recovered.get("clock"):
            t.append(f"\nClock: {recovered['clock']}\n")
    if outage in OUTAGE_WORDS:
        t.append(f"\nOutage rule '{outage}': a core outage {OUTAGE_WORDS[outage]} (o changes it).")
    return t


class RecoveryScreen(ModalScreen[None]):
    """The report; ``escape``, ``enter`` or ``r`` closes it."""

    BINDINGS = [Binding("escape,enter,r", "close", "Close")]

    def __init__(self, recovered: dict[str, Any] | None, known: bool, outage: str | None) -> None:
        super().__init__(classes="dialog-screen")
        self.report = report_text(recovered, known, outage)

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog", id="recovery-dialog") as v:
            v.border_title = "What the core recovered from its log"
            with VerticalScroll(id="recovery-body"):
                yield Static(self.report)
            with Horizontal(classes="buttons"):
                yield Button("Close esc", id="close", compact=True)

    def on_button_pressed(self, event: Button.Pressed) -> None:
        event.stop()
        self.dismiss(None)

    def action_close(self) -> None:
        self.dismiss(None)

"""The monitor panel: everything known about the selected robot (the thesis's fig 4.5, live)."""
from __future__ import annotations

import time
from typing import Any

from rich.console import Group
from rich.table import Table
from rich.text import Text
from textual.app import ComposeResult
from textual.containers import VerticalScroll
from textual.widgets import Static

from robo_comp.tui.model import ConsoleModel, describe_event, task_label
from robo_comp.tui.widgets.robots_table import status_text
from robo_comp.tui.widgets.task_form import signature


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.2f}"
    if isinstance(v, (list, tuple)):
        if len(v) > 8:
            return "[" + ", ".join(_fmt(x) for x in v[:8]) + f", … ({len(v)})]"
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    if isinstance(v, dict):
        return ", ".join(f"{k} {_fmt(x)}" for k, x in v.items())
    return str(v)


class MonitorPanel(VerticalScroll):
    """Monitor data of one robot: status, pose, current/queued/done tasks, advertised tasks,
    sensor readings and its recent events."""

    DEFAULT_CSS = """
    MonitorPanel { height: 1fr; }
    MonitorPanel > Static { width: 100%; }
    """

    def __init__(self, id: str | None = None) -> None:
        super().__init__(id=id)
        self.border_title = "Monitor"
        self.tag: int | None = None

    def compose(self) -> ComposeResult:
        yield Static("Select a robot in the table.", id="monitor-body")

    def show(self, model: ConsoleModel, tag: int | None) -> None:
        """Draw robot ``tag`` from the model."""
        self.tag = tag
        body = self.query_one("#monitor-body", Static)
        if tag is None or tag not in model.robots:
            self.border_title = "Monitor"
            body.update("Select a robot in the table." if model.robots else "No robots yet: start your robot host.")
            return
        row = dict(model.robots[tag])
        d = model.details.get(tag, {})
        self.border_title = f"Monitor · robot {tag}"
        grid = Table.grid(padding=(0, 1))
        grid.add_column(style="bold cyan", no_wrap=True)
        grid.add_column(ratio=1)
        head = Text.assemble((f"{tag} ", "bold"), (str(row.get("robot_id", "")), "dim"), "  ",
                             status_text(row.get("status", "?"), bool(row.get("moving"))))
        if row.get("team"):
            head.append(f"  team {row['team']}", style="dim")
        grid.add_row("robot", head)
        sigma = row.get("sigma") or 0.0
        grid.add_row("position", f"({row.get('x', 0):.2f}, {row.get('y', 0):.2f}) ± {sigma:.2f} cells  "
                                 f"heading {row.get('heading', 0):.0f}°")
        grid.add_row("task", task_label(d.get("task", row.get("task")) if d else row.get("task")))
        queued = d.get("queued") or []
        grid.add_row("queue", ", ".join(task_label(q) for q in queued) if queued
                     else str(row.get("queue", 0) or "empty"))
        done = (d.get("done") or [])[-4:]
        if done:
            lines = Text()
            for i, t in enumerate(reversed(done)):
                if i:
                    lines.append("\n")
                mark, style = ("✓", "green") if t.get("ok") else ("✗", "red")
                lines.append(f"{mark} ", style=style)
                lines.append(f"{task_label(t)} {t.get('status') or t.get('state', '')}")
                if t.get("result") not in (None, {}, []):
                    res = _fmt(t["result"])
                    lines.append(f" → {res[:60]}{'…' if len(res) > 60 else ''}", style="dim")
            grid.add_row("done", lines)
        adv = d.get("advertised") or []
        if adv:
            grid.add_row("can do", "\n".join(signature(s) for s in adv))
        sensors = d.get("sensors") or {}
        if sensors:
            grid.add_row("sensors", "\n".join(f"{k}: {_fmt(v)}" for k, v in sensors.items()))
        if d.get("last_report"):
            age = max(0.0, model.wall_clock() - float(d["last_report"]))
            grid.add_row("reported", f"{age:.1f} s ago")
        recent = model.recent(tag, 6)
        parts: list[Any] = [grid]
        if recent:
            ev = Text()
            for i, e in enumerate(recent):
                if i:
                    ev.append("\n")
                ev.append(time.strftime("%H:%M:%S ", time.localtime(e.t)), style="dim")
                ev.append(describe_event(e))
            parts += [Text("recent events", style="bold cyan"), ev]
        body.update(Group(*parts))

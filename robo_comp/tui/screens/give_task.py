"""The give-task form: pick one of the robot's advertised tasks, fill its arguments, now or queued."""
from __future__ import annotations

import asyncio
from typing import Any

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Button, Input, Label, RadioButton, RadioSet, Select, Static

from robo_comp.tui.widgets.choices import Choice
from robo_comp.tui.widgets.task_form import ArgField, signature


class GiveTaskScreen(ModalScreen[dict[str, Any] | None]):
    """Dismisses with ``{"tag", "task", "args", "queue"}`` or None when cancelled.

    Every argument is checked against its advertised type before the form may be sent.
    """

    BINDINGS = [Binding("escape", "cancel", "Cancel"), Binding("ctrl+g", "give", "Give", show=True)]

    def __init__(self, tag: int, advertised: list[dict[str, Any]], task: str | None = None) -> None:
        super().__init__(classes="dialog-screen")
        self.tag = tag
        self.advertised = {s["name"]: s for s in advertised}
        self.initial = task if task in self.advertised else next(iter(self.advertised), None)
        self._lock = asyncio.Lock()
        self._shown: str | None = ""

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog", id="task-dialog") as v:
            v.border_title = f"Give a task to robot {self.tag}"
            yield Select([(signature(s), n) for n, s in self.advertised.items()], value=self.initial,
                         allow_blank=False, id="task", compact=True)
            yield Static("", id="task-help", classes="help")
            yield VerticalScroll(id="args")
            with RadioSet(id="mode", compact=True):
                yield Choice("now: interrupt the current task", value=True, id="now")
                yield Choice("queue: after the current and queued ones", id="queue")
            yield Label("", id="form-error", classes="error")
            with Horizontal(classes="buttons"):
                yield Button("Give ^g", variant="primary", id="give", compact=True)
                yield Button("Cancel esc", id="cancel", compact=True)

    async def on_mount(self) -> None:
        await self._show_args(self.initial)

    @on(Select.Changed, "#task")
    async def _task_changed(self, event: Select.Changed) -> None:
        await self._show_args(event.value if isinstance(event.value, str) else None)

    async def _show_args(self, name: str | None) -> None:
        async with self._lock:  # mount and a Select.Changed may ask at the same time
            if name == self._shown:
                return
            self._shown = name
            await self._rebuild(name)

    async def _rebuild(self, name: str | None) -> None:
        box = self.query_one("#args", VerticalScroll)
        await box.remove_children()
        spec = self.advertised.get(name or "")
        self.query_one("#task-help", Static).update(spec.get("description", "") if spec else "")
        if spec is None:
            return
        fields = [ArgField(a, i) for i, a in enumerate(spec.get("args") or [])]
        if fields:
            await box.mount(*fields)
            self.call_after_refresh(self._focus_first)
        else:
            await box.mount(Label("this task takes no arguments", classes="help"))

    def _focus_first(self) -> None:
        for w in self.query("ArgField Input, ArgField Checkbox"):
            w.focus()
            break

    def values(self) -> dict[str, Any]:
        """The checked form; ``ValueError`` naming the first field that does not fit."""
        task = self.query_one("#task", Select).value
        if not isinstance(task, str):
            raise ValueError("choose a task")
        args = [f.value() for f in self.query(ArgField)]
        queue = bool(self.query_one("#queue", RadioButton).value)
        return {"tag": self.tag, "task": task, "args": args, "queue": queue}

    @on(Input.Changed)
    def _changed(self, event: Input.Changed) -> None:
        """Say at once what is wrong with the field being typed."""
        result = event.validation_result
        err = self.query_one("#form-error", Label)
        if result is not None and not result.is_valid and event.value:
            err.update(f"✗ {result.failure_descriptions[0]}")
        else:
            err.update("")

    @on(Input.Submitted)
    def _submitted(self, event: Input.Submitted) -> None:
        event.stop()
        inputs = list(self.query("ArgField Input"))
        if event.input in inputs and inputs.index(event.input) < len(inputs) - 1:
            inputs[inputs.index(event.input) + 1].focus()
        else:
            self.action_give()

    @on(Button.Pressed, "#give")
    def _give_pressed(self, event: Button.Pressed) -> None:
        event.stop()
        self.action_give()

    @on(Button.Pressed, "#cancel")
    def _cancel_pressed(self, event: Button.Pressed) -> None:
        event.stop()
        self.dismiss(None)

    def action_give(self) -> None:
        try:
            values = self.values()
        except ValueError as e:
            self.query_one("#form-error", Label).update(f"✗ {e}")
            return
        self.dismiss(values)

    def action_cancel(self) -> None:
        self.dismiss(None)

"""Small forms of the referee console: penalty, disqualify, broadcast, extend, approve an upload."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widgets import Button, Input, Label, Select


@dataclass
class Field:
    """One form field: ``kind`` is ``text``, ``number`` or ``select`` (with ``options``)."""

    name: str
    label: str
    kind: str = "text"
    options: list[tuple[str, Any]] = field(default_factory=list)
    value: Any = None
    required: bool = True


class FormScreen(ModalScreen[dict[str, Any] | None]):
    """A titled form; dismisses with the values by field name, or None when cancelled."""

    BINDINGS = [Binding("escape", "cancel", "Cancel")]

    def __init__(self, title: str, fields: list[Field], submit: str = "OK", danger: bool = False) -> None:
        super().__init__(classes="dialog-screen")
        self.title_text = title
        self.fields = fields
        self.submit = submit
        self.danger = danger

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog", id="form-dialog") as v:
            v.border_title = self.title_text
            for f in self.fields:
                yield Label(f.label)
                if f.kind == "select":
                    yield Select(f.options, value=f.value if f.value is not None else Select.NULL,
                                 allow_blank=f.value is None, id=f"f-{f.name}", compact=True)
                else:
                    yield Input(value="" if f.value is None else str(f.value), id=f"f-{f.name}", compact=True,
                                type="number" if f.kind == "number" else "text")
            yield Label("", id="form-error", classes="error")
            with Horizontal(classes="buttons"):
                yield Button(self.submit, variant="error" if self.danger else "primary", id="ok", compact=True)
                yield Button("Cancel esc", id="cancel", compact=True)

    def values(self) -> dict[str, Any]:
        """The form's values; ``ValueError`` naming the first missing or wrong field."""
        out: dict[str, Any] = {}
        for f in self.fields:
            w = self.query_one(f"#f-{f.name}")
            if isinstance(w, Select):
                v = w.value if w.value is not Select.NULL else None
            else:
                assert isinstance(w, Input)
                v = w.value.strip()
                if f.kind == "number" and v:
                    try:
                        v = float(v)
                    except ValueError:
                        raise ValueError(f"{f.label} must be a number") from None
                v = v if v != "" else None
            if v is None and f.required:
                raise ValueError(f"{f.label} is required")
            out[f.name] = v
        return out

    @on(Input.Submitted)
    def _submitted(self, event: Input.Submitted) -> None:
        event.stop()
        self._ok()

    @on(Button.Pressed)
    def _pressed(self, event: Button.Pressed) -> None:
        event.stop()
        if event.button.id == "ok":
            self._ok()
        else:
            self.dismiss(None)

    def _ok(self) -> None:
        try:
            values = self.values()
        except ValueError as e:
            self.query_one("#form-error", Label).update(f"✗ {e}")
            return
        self.dismiss(values)

    def action_cancel(self) -> None:
        self.dismiss(None)

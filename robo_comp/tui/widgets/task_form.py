"""The give-task form: one field per argument the robot advertises, checked before sending.

The robot advertises each task as ``{name, description, args: [{name, type, description}]}``
with the types ``int``, ``float``, ``str``, ``bool``, ``point`` and ``points``. :func:`parse_arg`
turns what the user typed into the value the core expects, or raises ``ValueError`` with a
sentence that says what to type instead; :class:`ArgValidator` shows that sentence under the
field while the user types.
"""
from __future__ import annotations

import json
import re
from typing import Any

from textual.app import ComposeResult
from textual.containers import Vertical
from textual.validation import ValidationResult, Validator
from textual.widgets import Checkbox, Input, Label

from robo_comp.protocol.taskspec import signature  # the core's own wording of a task
from robo_comp.tui.widgets.choices import Tick

#: What to type, by argument type (placeholder text).
HINTS = {
    "int": "a whole number, e.g. 12",
    "float": "a number, e.g. 2.5",
    "str": "text",
    "bool": "",
    "point": "x, y  e.g. 3, 4",
    "points": "x1, y1; x2, y2; …  e.g. 1,1; 5,1; 5,6",
}
_NUM = r"-?\d+(?:\.\d+)?"


def _number(text: str, what: str) -> float | int:
    t = text.strip()
    if re.fullmatch(r"-?\d+", t):
        return int(t)
    if re.fullmatch(_NUM, t):
        return float(t)
    raise ValueError(f"{what} must be a number, not {t!r}")


def _point(text: str, what: str) -> list[float | int]:
    t = text.strip().strip("()[]")
    parts = [p for p in re.split(r"[,\s]+", t) if p]
    if len(parts) != 2:
        raise ValueError(f"{what} needs two numbers x, y")
    return [_number(p, what) for p in parts]


def parse_arg(spec: dict[str, Any], text: str) -> Any:
    """The value of argument ``spec`` typed as ``text``; ``ValueError`` with advice if it does not fit."""
    kind = spec.get("type", "str")
    name = spec.get("name", "argument")
    t = text.strip()
    if kind == "str":
        return text
    if kind == "bool":
        low = t.lower()
        if low in ("true", "yes", "1", "on"):
            return True
        if low in ("false", "no", "0", "off"):
            return False
        raise ValueError(f"{name} must be true or false")
    if not t:
        raise ValueError(f"{name} is required ({HINTS[kind]})")
    if kind == "int":
        if not re.fullmatch(r"-?\d+", t):
            raise ValueError(f"{name} must be a whole number, not {t!r}")
        return int(t)
    if kind == "float":
        return _number(t, name)
    if kind == "point":
        return _point(t, name)
    if kind == "points":
        if t.startswith("[["):
            try:
                pts = json.loads(t)
            except ValueError:
                raise ValueError(f"{name}: not a valid list of points") from None
            if not (isinstance(pts, list) and pts and all(isinstance(p, list) and len(p) == 2 for p in pts)):
                raise ValueError(f"{name} must be a list of [x, y] points")
            return [[_number(str(c), name) for c in p] for p in pts]
        chunks = [c for c in re.split(r"[;|]", t) if c.strip()]
        if not chunks:
            raise ValueError(f"{name} needs at least one point")
        if len(chunks) > 1000:
            raise ValueError(f"{name} may have at most 1000 points")
        return [_point(c, f"{name} point {i + 1}") for i, c in enumerate(chunks)]
    raise ValueError(f"{name} has an unknown type {kind!r}")


class ArgValidator(Validator):
    """Validates one argument field as the user types."""

    def __init__(self, spec: dict[str, Any]) -> None:
        super().__init__()
        self.spec = spec

    def validate(self, value: str) -> ValidationResult:
        try:
            parse_arg(self.spec, value)
        except ValueError as e:
            return self.failure(str(e))
        return self.success()


class ArgField(Vertical):
    """A label and an input (or a checkbox for ``bool``) for one task argument."""

    DEFAULT_CSS = """
    ArgField { height: auto; }
    ArgField > Label { color: $text-muted; }
    """

    def __init__(self, spec: dict[str, Any], index: int) -> None:
        super().__init__(classes="arg-field")
        self.spec = spec
        self.index = index

    def compose(self) -> ComposeResult:
        s = self.spec
        desc = f" — {s['description']}" if s.get("description") else ""
        if s.get("type") == "bool":
            yield Tick(f"{s['name']}{desc}", id=f"arg-{self.index}", compact=True)
            return
        yield Label(f"[b]{s['name']}[/b]: {s['type']}{desc}", markup=True)
        yield Input(placeholder=HINTS.get(s.get("type", "str"), ""), id=f"arg-{self.index}",
                    validators=[ArgValidator(s)], compact=True, valid_empty=s.get("type") == "str")

    def value(self) -> Any:
        """The parsed value (``ValueError`` when it does not fit)."""
        if self.spec.get("type") == "bool":
            return self.query_one(Checkbox).value
        return parse_arg(self.spec, self.query_one(Input).value)


__all__ = ["ArgField", "ArgValidator", "HINTS", "parse_arg", "signature"]

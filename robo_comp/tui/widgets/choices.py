"""Check boxes and radio buttons that show their state by a mark, not by colour alone.

Textual draws a checkbox as ``▐X▌`` and a radio button as ``▐●▌`` whether on or off, and tells the
two apart by colour only: on a monochrome terminal, or to a colour-blind student, "extension" and
"code", "now" and "queue" look the same. These draw the mark only when the box is on.
"""
from __future__ import annotations

from textual.content import Content
from textual.widgets import Checkbox, RadioButton


class Tick(Checkbox):
    """A checkbox: ``▐X▌`` when on, ``▐ ▌`` when off."""

    @property
    def _button(self) -> Content:
        self.BUTTON_INNER = "X" if self.value else " "
        return super()._button


class Choice(RadioButton):
    """A radio button: ``▐●▌`` when chosen, ``▐ ▌`` when not."""

    @property
    def _button(self) -> Content:
        self.BUTTON_INNER = "●" if self.value else " "
        return super()._button

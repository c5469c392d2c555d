"""Textual messages the consoles post: from the core link to the app, and between widgets."""
from __future__ import annotations

from typing import Any

from textual.message import Message

from robo_comp.link import LinkState


class CoreEvent(Message):
    """An event the core pushed (``robot.position``, ``task.done``, ``match.phase``, ...)."""

    def __init__(self, topic: str, team: str | None, data: dict[str, Any]) -> None:
        super().__init__()
        self.topic = topic
        self.team = team
        self.data = data


class LinkChanged(Message):
    """The link to the core changed state (connecting, connected, reconnecting, closed)."""

    def __init__(self, state: LinkState, detail: str, info: dict[str, Any]) -> None:
        super().__init__()
        self.state = state
        self.detail = detail
        self.info = info


class RobotSelected(Message):
    """The user selected robot ``tag`` (in the robots table or on the map)."""

    def __init__(self, tag: int | None) -> None:
        super().__init__()
        self.tag = tag

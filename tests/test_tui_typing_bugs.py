"""Bugs the type checker found in the consoles, each shown through a real Textual app."""
from __future__ import annotations

import asyncio

import pytest

from robo_comp.tui.team_app import TeamApp
from robo_comp.tui.testing import CannedLink, until

FIXED = {"clock": lambda: 100.0, "wall_clock": lambda: 1002.5, "poll": False}


def test_the_console_keeps_textuals_feature_flags(monkeypatch: pytest.MonkeyPatch) -> None:
    """The console kept what the core serves in ``self.features``, the attribute where Textual's
    App keeps its flags from ``TEXTUAL=debug,devtools``: ``TEXTUAL=debug`` did nothing in a console
    (``app.debug`` False). Now both live side by side."""
    monkeypatch.setenv("TEXTUAL", "debug")

    async def scenario() -> None:
        app = TeamApp(link=CannedLink("team", "red", upload=True), **FIXED)  # type: ignore[arg-type]
        async with app.run_test(size=(80, 24)) as pilot:
            await until(pilot, lambda: app.core_features.get("upload"), 15, "feature detection")
            assert "debug" in app.features and app.debug
            assert "upload" not in app.features  # the core's features stay out of Textual's flags

    asyncio.run(scenario())

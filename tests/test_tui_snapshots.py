"""Snapshot tests of the consoles' main screens at 80×24 and 160×48 (pytest-textual-snapshot).

The apps run against a canned link (fixed robots, scores, events; a paused clock), so every
run draws the same screen. Update after an intended change with ``pytest --snapshot-update``
and look at the report it writes.
"""
from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip("pytest_textual_snapshot")

from robo_comp.tui.referee_app import RefereeApp  # noqa: E402
from robo_comp.tui.team_app import TeamApp  # noqa: E402
from robo_comp.tui.testing import CannedLink  # noqa: E402

SIZES = [(80, 24), (160, 48)]
FIXED = {"clock": lambda: 100.0, "wall_clock": lambda: 1002.5, "poll": False}


@pytest.fixture(autouse=True)
def utc(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Event times are shown in local time: pin the zone so snapshots match everywhere."""
    monkeypatch.setenv("TZ", "UTC")
    time.tzset()
    yield
    monkeypatch.undo()
    time.tzset()


async def quiet(pilot: Any) -> None:
    """Let the canned data arrive, then clear the toasts it raised."""
    await pilot.pause(0.3)
    pilot.app.clear_notifications()
    await pilot.pause()


def team() -> TeamApp:
    return TeamApp(link=CannedLink("team", "red"), **FIXED)  # type: ignore[arg-type]


def referee() -> RefereeApp:
    return RefereeApp(link=CannedLink("referee", None), **FIXED)  # type: ignore[arg-type]


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_team_console(snap_compare: Any, size: tuple[int, int]) -> None:
    assert snap_compare(team(), terminal_size=size, run_before=quiet)


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_referee_console(snap_compare: Any, size: tuple[int, int]) -> None:
    assert snap_compare(referee(), terminal_size=size, run_before=quiet)


def test_team_console_narrow_map_panel(snap_compare: Any) -> None:
    assert snap_compare(team(), terminal_size=(80, 24), run_before=quiet, press=["v"])


def test_give_task_form(snap_compare: Any) -> None:
    async def open_form(pilot: Any) -> None:
        await quiet(pilot)
        await pilot.press("t")
        await pilot.pause(0.3)
        await pilot.press("1", "2", "enter", "x")  # a valid x, a wrong y
        await pilot.pause(0.1)

    assert snap_compare(team(), terminal_size=(80, 24), run_before=open_form)


def test_upload_dialog(snap_compare: Any, tmp_path_factory: pytest.TempPathFactory) -> None:
    folder = tmp_path_factory.mktemp("extensions", numbered=False)
    (folder / "square.py").write_text("NAME = 'square'\n")
    (folder / "notes.txt").write_text("not shown: only .py files are listed\n")
    app = TeamApp(link=CannedLink("team", "red", upload=True), upload_dir=folder, **FIXED)  # type: ignore[arg-type]

    async def open_dialog(pilot: Any) -> None:
        await quiet(pilot)
        await pilot.press("u")
        await pilot.pause(0.5)

    assert snap_compare(app, terminal_size=(80, 24), run_before=open_dialog)

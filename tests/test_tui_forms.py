"""Pilot tests of the consoles' dialogs against a canned core (no processes: fast and exact)."""
from __future__ import annotations

import asyncio
from pathlib import Path

from robo_comp.tui.referee_app import RefereeApp
from robo_comp.tui.screens.confirm import ConfirmScreen
from robo_comp.tui.screens.forms import FormScreen
from robo_comp.tui.screens.give_task import GiveTaskScreen
from robo_comp.tui.screens.upload import UploadScreen
from robo_comp.tui.team_app import TeamApp
from robo_comp.tui.testing import CannedLink, notifications, screen_text, until

FIXED = {"clock": lambda: 100.0, "wall_clock": lambda: 1002.5, "poll": False}
GOOD = '''MANIFEST = {"name": "square", "version": "1.0", "kind": "extension", "tasks": {}}\n'''
BAD = '''MANIFEST = {"name": "square", "version": "1.0", "kind": "extension", "tasks": {}}\n\n\ndef init(robot, extra):\n    pass\n'''


def test_upload_dialog_shows_each_verdict(tmp_path: Path) -> None:
    (tmp_path / "good.py").write_text(GOOD)
    (tmp_path / "bad_ext.py").write_text(BAD)
    link = CannedLink("team", "red", upload=True)

    async def scenario() -> None:
        app = TeamApp(link=link, upload_dir=tmp_path, **FIXED)  # type: ignore[arg-type]
        async with app.run_test(size=(80, 24)) as pilot:
            await until(pilot, lambda: app.core_features.get("upload"), 15, "feature detection")
            await pilot.press("u")
            dlg = await until(pilot, lambda: isinstance(app.screen, UploadScreen) and app.screen, 15, "the dialog")
            await pilot.press("ctrl+u")  # nothing picked yet
            assert "pick a .py file first" in screen_text(app)
            dlg.query_one("#path").value = str(tmp_path / "bad_ext.py")
            await pilot.press("ctrl+u")
            await until(pilot, lambda: "signature" in screen_text(app), 15, "the checked error")
            assert "bad_ext.py:9: signature: init must be declared as def init(robot)" in screen_text(app)
            dlg.query_one("#path").value = str(tmp_path / "good.py")
            await pilot.press("ctrl+u")
            await until(pilot, lambda: "✓ robot 101: square 1.0" in screen_text(app), 15, "the verdicts")
            sent = [b for t, b in link.sent if t == "upload" and "source" in b]
            assert sent[-1]["tags"] == [101] and sent[-1]["kind"] == "extension"  # the selected robot
            assert sent[-1]["source"] == GOOD and sent[-1]["run"] is False
            await pilot.click("#all")  # every connected robot, as code, run at once
            await pilot.click("#code")
            await pilot.click("#run")
            await pilot.press("ctrl+u")
            await until(pilot, lambda: "✓ robot 102" in screen_text(app), 15, "both verdicts")
            sent = [b for t, b in link.sent if t == "upload" and "source" in b]
            assert (sent[-1]["tags"], sent[-1]["kind"], sent[-1]["run"]) == ([101, 102], "code", True)

    asyncio.run(scenario())


def test_a_path_typed_into_the_upload_dialog_is_sent(tmp_path: Path) -> None:
    """Typed key by key into the path field, then ctrl+u: that file is sent (ctrl+u used to be the
    field's own "delete to the start", so the typed path was wiped and nothing sent); a relative
    path is taken in the folder the picker shows."""
    (tmp_path / "extensions").mkdir()
    (tmp_path / "extensions" / "good.py").write_text(GOOD)
    link = CannedLink("team", "red", upload=True)

    async def scenario() -> None:
        app = TeamApp(link=link, upload_dir=tmp_path, **FIXED)  # type: ignore[arg-type]
        async with app.run_test(size=(80, 24)) as pilot:
            await until(pilot, lambda: app.core_features.get("upload"), 15, "feature detection")
            for typed in (str(tmp_path / "extensions" / "good.py"), "extensions/good.py"):
                await pilot.press("u")
                dlg = await until(pilot, lambda: isinstance(app.screen, UploadScreen) and app.screen, 15, "the dialog")
                await pilot.click("#path")
                await pilot.press(*typed)
                await until(pilot, lambda: dlg.query_one("#path").value == typed, 15, "the typed path")
                before = len(link.sent)
                await pilot.press("ctrl+u")
                await until(pilot, lambda: "✓ robot 101: square 1.0" in screen_text(app), 15, f"the verdict on {typed}")
                sent = [b for t, b in link.sent[before:] if t == "upload"]
                assert [(b["filename"], b["source"]) for b in sent] == [("good.py", GOOD)], sent
                await pilot.press("escape")
                await until(pilot, lambda: not isinstance(app.screen, UploadScreen), 15, "the dialog closed")

    asyncio.run(scenario())


def test_task_form_sends_typed_arguments() -> None:
    link = CannedLink("team", "red")

    async def scenario() -> None:
        app = TeamApp(link=link, **FIXED)  # type: ignore[arg-type]
        async with app.run_test(size=(80, 24)) as pilot:
            await until(pilot, lambda: app.selected == 101, 15, "the first robot selected")
            await pilot.press("t")
            form = await until(pilot, lambda: isinstance(app.screen, GiveTaskScreen) and app.screen, 15, "the form")
            form.query_one("#task").value = "followPath"
            await until(pilot, lambda: len(form.query("ArgField")) == 1, 15, "followPath's field")
            field = form.query_one("#arg-0")
            field.focus()  # a loaded machine may not have moved the focus there yet
            await until(pilot, lambda: field.has_focus, 15, "the field's focus")
            await pilot.press(*"1,1; 5,1; 5,6")
            await until(pilot, lambda: field.value == "1,1; 5,1; 5,6", 15, "the typed points")
            await pilot.click("#queue")
            await pilot.press("ctrl+g")
            await until(pilot, lambda: any(t == "give" for t, _ in link.sent), 15, "the give request")
            body = next(b for t, b in link.sent if t == "give")
            assert body == {"tag": 101, "task": "followPath", "args": [[[1, 1], [5, 1], [5, 6]]],
                            "queue": True}

    asyncio.run(scenario())


def test_referee_approves_a_pending_upload_and_disqualifies_with_confirmation() -> None:
    link = CannedLink("referee", None, upload=True)

    async def scenario() -> None:
        app = RefereeApp(link=link, **FIXED)  # type: ignore[arg-type]
        async with app.run_test(size=(120, 40)) as pilot:
            await until(pilot, lambda: app.core_features.get("approve"), 15, "feature detection")
            link.on_event("upload.pending", "red", {"upload_id": 4, "team": "red", "tags": [101], "filename": "square.py",
                                                   "sha256": "ab12", "by": "red"})
            await until(pilot, lambda: any("press a to approve" in n for n in notifications(app)), 15, "the toast")
            await pilot.press("a")
            await until(pilot, lambda: isinstance(app.screen, FormScreen), 15, "the approve form")
            await pilot.click("#ok")
            await until(pilot, lambda: any(t == "approve" and b for t, b in link.sent), 15, "the approve request")
            assert [b for t, b in link.sent if t == "approve" and b][-1] == {"upload_id": 4, "ok": True}
            # disqualify the selected robot: form, then a confirmation
            await pilot.press("d")
            form = await until(pilot, lambda: isinstance(app.screen, FormScreen) and app.screen, 15, "the form")
            form.query_one("#f-reason").value = "rammed robot 104"
            await pilot.click("#ok")
            await until(pilot, lambda: isinstance(app.screen, ConfirmScreen), 15, "the confirmation")
            await pilot.press("y")
            await until(pilot, lambda: any(t == "disqualify" and b for t, b in link.sent), 15, "the request")
            assert [b for t, b in link.sent if t == "disqualify" and b][-1] == {"reason": "rammed robot 104",
                                                                                 "tag": 101}

    asyncio.run(scenario())


def test_clicking_a_robot_on_the_map_selects_it() -> None:
    async def scenario() -> None:
        app = TeamApp(link=CannedLink("team", "red"), **FIXED)  # type: ignore[arg-type]
        async with app.run_test(size=(160, 48)) as pilot:
            await until(pilot, lambda: app.selected == 101, 15, "the first robot selected")
            m = app.screen.query_one("#map")
            await pilot.pause(0.3)
            col, line = m.cell_to_screen(18, 3)
            # robot 102 stands at (18, 3): click its character (inside the border: +1, +1)
            await pilot.click("#map", offset=(col + 1, line + 1))
            await until(pilot, lambda: app.selected == 102, 15, "robot 102 selected")
            assert "Monitor · robot 102" in screen_text(app)

    asyncio.run(scenario())

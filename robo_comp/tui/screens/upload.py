"""Upload an extension (adds tasks) or code (replaces behaviour) from a file, and see the verdict."""
from __future__ import annotations

from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

from textual import on, work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widgets import Button, Checkbox, DirectoryTree, Input, RadioButton, RadioSet

from robo_comp.errors import RoboCompError
from robo_comp.sandbox.contract import MAX_SOURCE_BYTES as MAX_UPLOAD  # what the robots accept
from robo_comp.tui.widgets.choices import Choice, Tick
from robo_comp.tui.widgets.upload import PythonTree, UploadResult

Sender = Callable[[dict[str, Any]], Awaitable[dict[str, Any]]]


class UploadScreen(ModalScreen[None]):
    """Pick a ``.py`` file, choose extension or code and the robots, send, read the checked result.

    ``send(body)`` performs the ``upload`` request (the app's link); this screen never blocks:
    the request runs in a worker and STOP keeps working meanwhile.
    """

    # ctrl+u has priority: in the path field it would otherwise be the field's own "delete to the
    # start of the line", and the typed path was wiped instead of sent
    BINDINGS = [Binding("escape", "close", "Close"), Binding("ctrl+u", "send", "Send", show=True, priority=True)]

    def __init__(self, send: Sender, tag: int | None, all_tags: list[int], start: Path,
                 available: bool = True) -> None:
        super().__init__(classes="dialog-screen")
        self.send = send
        self.tag = tag
        self.all_tags = all_tags
        self.start = start
        self.available = available

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog", id="upload-dialog") as v:
            v.border_title = "Upload an extension or code"
            yield PythonTree(self.start, id="tree")
            yield Input(placeholder="path of a .py file (or pick one above)", id="path", compact=True)
            with Horizontal(id="upload-options"):
                with RadioSet(id="kind", compact=True):
                    yield Choice("extension (adds tasks)", value=True, id="extension")
                    yield Choice("code (replaces behaviour)", id="code")
                with Vertical(id="upload-flags"):
                    yield Tick("run it now (code)", id="run", compact=True)
                    yield Tick(f"all my robots ({len(self.all_tags)})", value=self.tag is None,
                                   id="all", compact=True)
            yield UploadResult("", id="upload-result")
            with Horizontal(classes="buttons"):
                yield Button("Send ^u", variant="primary", id="send", compact=True, disabled=not self.available)
                yield Button("Close esc", id="close", compact=True)

    def on_mount(self) -> None:
        if not self.available:
            self.query_one(UploadResult).show_error("uploads are not available on this core yet")

    @on(DirectoryTree.FileSelected)
    def _picked(self, event: DirectoryTree.FileSelected) -> None:
        event.stop()
        self.query_one("#path", Input).value = str(event.path)

    @on(Input.Submitted, "#path")
    def _path_submitted(self, event: Input.Submitted) -> None:
        event.stop()
        self.action_send()

    @on(Button.Pressed, "#send")
    def _send_pressed(self, event: Button.Pressed) -> None:
        event.stop()
        self.action_send()

    @on(Button.Pressed, "#close")
    def _close_pressed(self, event: Button.Pressed) -> None:
        event.stop()
        self.dismiss(None)

    def action_close(self) -> None:
        self.dismiss(None)

    def body(self) -> dict[str, Any]:
        """The ``upload`` request body; ``ValueError`` with a sentence when something is missing."""
        raw = self.query_one("#path", Input).value.strip()
        if not raw:
            raise ValueError("pick a .py file first")
        path = self.resolve(raw)
        if not path.is_file():
            raise ValueError(f"{path} is not a file")
        if path.stat().st_size > MAX_UPLOAD:
            raise ValueError(f"{path.name} is larger than {MAX_UPLOAD:,} bytes, the most a robot accepts")
        try:
            source = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as e:
            raise ValueError(f"cannot read {path.name}: {e}") from None
        tags = self.all_tags if self.query_one("#all", Checkbox).value or self.tag is None else [self.tag]
        if not tags:
            raise ValueError("there is no robot to send it to")
        kind = "code" if self.query_one("#code", RadioButton).value else "extension"
        return {"tags": list(tags), "filename": path.name, "source": source, "kind": kind,
                "run": bool(self.query_one("#run", Checkbox).value) and kind == "code"}

    def resolve(self, raw: str) -> Path:
        """The file a typed path names: ``~`` expanded; a relative path is taken in the folder the
        picker shows (``--upload-dir``), else in the current folder."""
        path = Path(raw).expanduser()
        if path.is_absolute():
            return path
        here = self.start / path
        return here if here.exists() or not path.exists() else path

    def action_send(self) -> None:
        if not self.available:
            return
        result = self.query_one(UploadResult)
        try:
            body = self.body()
        except ValueError as e:
            result.show_error(str(e))
            return
        result.show_busy(body["filename"])
        self.query_one("#send", Button).disabled = True
        self._upload(body)

    @work(exclusive=True, group="upload")
    async def _upload(self, body: dict[str, Any]) -> None:
        result = self.query_one(UploadResult)
        try:
            reply = await self.send(body)
        except RoboCompError as e:
            result.show_error(e.message)
            self.app.notify(e.message, title=f"Upload of {body['filename']} refused", severity="error",
                            timeout=8)
        else:
            ok = result.show_results(reply)
            self.app.notify("every robot accepted it" if ok else "some robots refused it; see the dialog",
                            title=f"Upload of {body['filename']}", severity="information" if ok else "error")
        finally:
            self.query_one("#send", Button).disabled = False

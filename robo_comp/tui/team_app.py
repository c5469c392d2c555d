"""The team console: ``robo-comp team --core URL --token T``.

It replaces the thesis's numbered text menus (list robots, monitor, give task, give code,
STOP, quit) with one live screen: a robots table, the selected robot's monitor data, a map,
the event log, a give-task form built from what the robot advertises, uploads with the
checked verdict, and STOP on ``ctrl+s`` (``ctrl+x`` for every robot) that works whatever
else is open or pending.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable
from functools import partial
from pathlib import Path
from typing import Any

from textual.screen import Screen

from robo_comp.errors import RoboCompError, UnknownTypeError

from robo_comp.tui.app import ConsoleApp
from robo_comp.tui.screens.give_task import GiveTaskScreen
from robo_comp.tui.screens.team import TeamScreen
from robo_comp.tui.screens.upload import UploadScreen


class TeamApp(ConsoleApp):
    """The console of one team."""

    TITLE = "robo_comp team console"
    CLIENT_NAME = "team-console"

    def __init__(self, core: str = "", token: str = "", *, upload_dir: Path | None = None, **kw: Any) -> None:
        super().__init__(core, token, **kw)
        self.upload_dir = upload_dir or Path.cwd()

    def main_screen(self) -> Screen[Any]:
        return TeamScreen(self.model, self.link.info.get("team") or "…")

    def connected(self, info: dict[str, Any]) -> None:
        team = info.get("team")
        screen = self.main()
        if team and isinstance(screen, TeamScreen) and screen.team != team:
            screen.set_team(team)
        if team:
            self.title = f"robo_comp · team {team}"

    # ------------------------------------------------------------------ give a task
    def action_give_task(self, task: str | None = None) -> None:
        """Open the give-task form for the selected robot."""
        if self.selected is None:
            self.notify("select a robot first", title="Give a task", severity="warning")
            return
        self.spawn(partial(self._open_task_form, self.selected, task), group="task-form", exclusive=True)

    async def _open_task_form(self, tag: int, task: str | None) -> None:
        adv = (self.model.details.get(tag) or {}).get("advertised")
        if not adv:
            reply = await self.call("tasks", tag=tag)
            if reply is None:
                return
            adv = reply.get("advertised") or []
        if not adv:
            self.notify(f"robot {tag} advertises no tasks", title="Give a task", severity="warning")
            return
        self.push_screen(GiveTaskScreen(tag, adv, task), self._task_form_done)

    def _task_form_done(self, values: dict[str, Any] | None) -> None:
        if values is not None:
            self.spawn(self.give(**values), group="give")

    async def give(self, tag: int, task: str, args: list[Any], queue: bool) -> dict[str, Any] | None:
        """Send a task; say how the core took it."""
        reply = await self.call("give", tag=tag, task=task, args=args, queue=queue,
                                title=f"Robot {tag} refused {task}")
        if reply is not None:
            how = (f"queued at position {reply.get('position')}" if reply.get("mode") == "queue"
                   else f"interrupts task #{reply['interrupts']}" if reply.get("interrupts") else "started")
            self.notify(f"task #{reply.get('task_id')} {how}", title=f"Robot {tag}: {task}")
        return reply

    # ------------------------------------------------------------------ uploads
    def action_upload(self) -> None:
        """Open the upload dialog (file picker, extension or code, the checked verdict)."""
        tags = sorted(t for t, r in self.model.robots.items() if r.get("status") == "connected")
        self.push_screen(UploadScreen(self.upload, self.selected, tags, self.upload_dir,
                                      available=self.core_features.get("upload", True)))

    async def upload(self, body: dict[str, Any]) -> dict[str, Any]:
        """The ``upload`` request (raises on refusal; the dialog shows the message)."""
        try:
            return await self.link.request("upload", timeout=30.0, **body)
        except RoboCompError as e:
            if e.code == "E_UNKNOWN_TYPE":
                self.core_features["upload"] = False
                self.refresh_bindings()
                raise UnknownTypeError("uploads are not available on this core yet") from None
            raise

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        if action == "upload":
            return self.feature("upload")
        return True

    # ------------------------------------------------------------------ palette
    def robot_commands(self, tag: int) -> list[tuple[str, str, Callable[[], Any]]]:
        out: list[tuple[str, str, Callable[[], Any]]] = []
        for spec in (self.model.details.get(tag) or {}).get("advertised") or []:
            out.append((f"Give robot {tag} {spec['name']}", spec.get("description", ""),
                        partial(self._palette_task, tag, spec["name"])))
        return out

    def _palette_task(self, tag: int, task: str) -> None:
        self.select_robot(tag)
        self.action_give_task(task)

    def console_commands(self) -> Iterable[tuple[str, str, Callable[[], Any]]]:
        yield from super().console_commands()
        yield "Give a task", "open the task form for the selected robot (t)", self.action_give_task
        yield "Upload an extension or code", "pick a .py file and send it to your robots (u)", self.action_upload

"""The built-in plugin: the thesis's predefined tasks and the simulated driver."""
from __future__ import annotations

from typing import Any

from robo_comp.plugins.hookspecs import hookimpl
from robo_comp.robots.drivers import ArenaDriver
from robo_comp.robots.builtin_tasks import BUILTIN_TASKS
from robo_comp.robots.steps import TaskSpec


class BuiltinPlugin:
    """goTo, followPath, examineArea and the ``sim`` driver (the host's simulated arena)."""

    @hookimpl
    def robo_comp_tasks(self) -> list[TaskSpec]:
        """The predefined tasks (thesis 3.4.1)."""
        return list(BUILTIN_TASKS)

    @hookimpl
    def robo_comp_driver(self, kind: str, options: dict[str, Any]) -> ArenaDriver | None:
        """The simulated driver for ``kind == "sim"``: options ``arena``, ``localization``, ``robot_id``."""
        if kind != "sim":
            return None
        return ArenaDriver(options["arena"], options["robot_id"], options["localization"])


plugin = BuiltinPlugin()

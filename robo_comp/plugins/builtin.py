"""The built-in plugin: the thesis's predefined tasks and the simulated driver."""
from __future__ import annotations

from typing import Any

from robo_comp.plugins.hookspecs import hookimpl
from robo_comp.robots.body import Body
from robo_comp.robots.builtin_tasks import BUILTIN_TASKS
from robo_comp.robots.steps import TaskSpec


class BuiltinPlugin:
    """goTo, followPath, examineArea and the ``sim`` driver (grid kinematics)."""

    @hookimpl
    def robo_comp_tasks(self) -> list[TaskSpec]:
        """The predefined tasks (thesis 3.4.1)."""
        return list(BUILTIN_TASKS)

    @hookimpl
    def robo_comp_driver(self, kind: str, options: dict[str, Any]) -> Body | None:
        """The simulated grid driver for ``kind == "sim"``."""
        if kind != "sim":
            return None
        return Body(float(options.get("x", 0)), float(options.get("y", 0)), float(options.get("heading", 0)),
                    float(options.get("speed", 2.0)), float(options.get("turn_rate", 180.0)))


plugin = BuiltinPlugin()

"""The built-in plugin: the thesis's predefined tasks and the simulated driver."""
from __future__ import annotations

from typing import Any

from robo_comp.errors import UnavailableError
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
    def robo_comp_driver(self, kind: str, options: dict[str, Any]) -> Any:
        """``sim``: the simulated driver (options ``arena``, ``localization``, ``robot_id``).
        ``er1``: an ER1 through its robot control center (options ``rcc``: one ``HOST:PORT`` per
        robot, ``index`` of this robot, ``cell_cm``, the start pose ``x``, ``y``, ``heading``).
        ``ros2``: a ROS 2 robot over DDS (options ``ros2_ns``: one namespace per robot,
        ``ros2_domain``, ``ros2_speed`` in m/s, and ``index``, ``cell_cm``, the start pose)."""
        if kind == "sim":
            return ArenaDriver(options["arena"], options["robot_id"], options["localization"])
        if kind == "er1":
            from robo_comp.robots.er1 import ER1Driver, RCCLink

            rcc = options.get("rcc") or []
            i = int(options.get("index", 0))
            if i >= len(rcc):
                raise UnavailableError(f"robot {i + 1} has no robot control center: give one --rcc HOST:PORT per robot")
            return ER1Driver(RCCLink(rcc[i]), cell_cm=options["cell_cm"], x=options["x"], y=options["y"],
                             heading=options.get("heading", 0.0))
        if kind == "ros2":
            from robo_comp.robots.ros2.bus import Bus
            from robo_comp.robots.ros2.driver import ROS2Driver

            names = options.get("ros2_ns") or []
            i = int(options.get("index", 0))
            if i >= len(names):
                raise UnavailableError(f"robot {i + 1} has no ROS 2 namespace: give one --ros2-ns NS per robot")
            return ROS2Driver(Bus.shared(int(options.get("ros2_domain", 0))), names[i],
                              cell_m=options["cell_cm"] / 100.0, x=options["x"], y=options["y"],
                              heading=options.get("heading", 0.0), max_speed=float(options.get("ros2_speed", 0.2)))
        return None


plugin = BuiltinPlugin()

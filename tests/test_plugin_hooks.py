"""Every hookspec is called where its docstring says: the host-side hooks through a real host and core."""
from __future__ import annotations

import ast
import threading
import time
from pathlib import Path

from robo_comp.client import resolve_core
from robo_comp.plugins import hookspecs
from robo_comp.plugins.hookspecs import hookimpl
from robo_comp.plugins.manager import get_plugin_manager
from robo_comp.robots.host import RobotHost

ROOT = Path(__file__).resolve().parent.parent / "robo_comp"
SQUARE = (ROOT / "teams" / "template" / "extensions" / "square.py").read_text()


def test_every_hookspec_is_called_by_robo_comp():
    """A hookspec nobody calls promises what does not happen: each must be called as ``hook.NAME``
    (or by name through a helper) somewhere in robo_comp outside the hookspecs module."""
    specs = [n.name for n in ast.parse(Path(hookspecs.__file__).read_text()).body
             if isinstance(n, ast.FunctionDef)]
    assert len(specs) >= 9
    code = "\n".join(p.read_text() for p in ROOT.rglob("*.py") if p.name != "hookspecs.py")
    uncalled = [s for s in specs if f"hook.{s}" not in code and f'"{s}"' not in code]
    assert not uncalled, f"hookspecs never called: {uncalled}"


class Recorder:
    """A host-side plugin that senses a thermometer and records the extensions it is told about."""

    def __init__(self) -> None:
        self.loaded: list[tuple[int, str, str, list[str]]] = []
        self.unloaded: list[tuple[int, str]] = []

    @hookimpl
    def robo_comp_sense(self, robot):
        return {"thermo_c": 21.5, "who": robot.robot_id}

    @hookimpl
    def robo_comp_extension_loaded(self, tag, name, version, sha256, tasks):
        assert len(sha256) == 64
        self.loaded.append((tag, name, version, tasks))

    @hookimpl
    def robo_comp_extension_unloaded(self, tag, name):
        self.unloaded.append((tag, name))


class Broken:
    """A plugin whose sense hook raises: the host logs it and goes on."""

    @hookimpl
    def robo_comp_sense(self, robot):
        raise RuntimeError("broken thermometer")


def test_host_calls_sense_and_extension_hooks(core):
    pm = get_plugin_manager()
    rec = Recorder()
    pm.register(rec)
    pm.register(Broken())
    host = RobotHost(resolve_core(str(core.state)), core.host_token("red"), 1, plugins=pm)
    th = threading.Thread(target=host.run, kwargs={"duration": 40}, daemon=True)
    th.start()
    try:
        red = core.client("red")
        t_end = time.monotonic() + 15
        sensors: dict = {}
        tag = None
        while time.monotonic() < t_end:
            robots = red.robots()
            if robots:
                tag = robots[0]["tag"]
                sensors = red.monitor(tag).get("sensors") or {}
                if "thermo_c" in sensors:
                    break
            time.sleep(0.1)
        assert sensors.get("thermo_c") == 21.5, sensors  # merged with the arena's own readings
        assert "front" in sensors and sensors["who"] == "red-1"
        red.upload([tag], "square.py", SQUARE)
        red.upload([tag], "square.py", SQUARE.replace('"version": "1.0"', '"version": "1.1"'))
        red.unload([tag], "square")
        t_end = time.monotonic() + 5
        while len(rec.unloaded) < 2 and time.monotonic() < t_end:
            time.sleep(0.05)
        assert rec.loaded == [(tag, "square", "1.0", ["square"]), (tag, "square", "1.1", ["square"])]
        assert rec.unloaded == [(tag, "square"), (tag, "square")]  # replaced by 1.1, then unloaded
    finally:
        host.stop()
        th.join(5)

"""The plugin manager: hookspecs, built-ins and the ``robo_comp`` entry-point group."""
from __future__ import annotations

import pluggy

from robo_comp.plugins import hookspecs

ENTRY_POINT_GROUP = "robo_comp"


def get_plugin_manager(load_entry_points: bool = True) -> pluggy.PluginManager:
    """A fresh plugin manager with robo_comp's hookspecs and every installed plugin.

    Built-in plugins are declared as entry points in robo_comp's own ``pyproject.toml``, so
    the same mechanism loads ours and third parties'. ``check_pending()`` refuses hook
    implementations that match no hookspec (a typo in a hook name is an error, not silence).
    """
    pm = pluggy.PluginManager(hookspecs.PROJECT)
    pm.add_hookspecs(hookspecs)
    if load_entry_points:
        pm.load_setuptools_entrypoints(ENTRY_POINT_GROUP)
    pm.check_pending()
    return pm

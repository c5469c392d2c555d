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


def load_rules(spec: str) -> pluggy.PluginManager:
    """A plugin manager whose scoring rules are the plugin ``MODULE:OBJECT`` instead of the
    default ``sar_rules`` (which is blocked). Raises :class:`FieldError` with a clear message."""
    import importlib

    from robo_comp.errors import FieldError

    mod_name, _, attr = spec.partition(":")
    try:
        obj = getattr(importlib.import_module(mod_name), attr or "plugin")
    except (ImportError, AttributeError) as e:
        raise FieldError(f"cannot load the rules plugin {spec!r}: {e}") from None
    pm = pluggy.PluginManager(hookspecs.PROJECT)
    pm.add_hookspecs(hookspecs)
    pm.set_blocked("sar_rules")
    pm.load_setuptools_entrypoints(ENTRY_POINT_GROUP)
    pm.register(obj, name=f"rules:{spec}")
    pm.check_pending()
    return pm

"""Task descriptions: what a robot advertises, and the checks run on every task call.

A robot advertises each task it can run as a plain map::

    {"name": "goTo", "description": "...", "args": [{"name": "x", "type": "int", "description": "..."}]}

Argument types: ``int``, ``float``, ``str``, ``bool``, ``point`` (``[x, y]``) and ``points``
(a list of points). :func:`check_args` validates a call against such a description; the core
runs it before queueing a task and the robot host runs it again before starting one.
"""
from __future__ import annotations

import math
from typing import Any

from robo_comp.errors import BadTaskError, FieldError

ARG_TYPES = ("int", "float", "str", "bool", "point", "points")
MAX_TASKS_ADVERTISED = 64
MAX_ARGS = 16


def _is_num(v: Any) -> bool:
    return type(v) is int or (type(v) is float and math.isfinite(v))


def _is_point(v: Any) -> bool:
    return type(v) in (list, tuple) and len(v) == 2 and all(_is_num(c) for c in v)


_CHECKS = {
    "int": lambda v: type(v) is int,
    "float": _is_num,
    "str": lambda v: type(v) is str,
    "bool": lambda v: type(v) is bool,
    "point": _is_point,
    "points": lambda v: type(v) in (list, tuple) and 0 < len(v) <= 1000 and all(_is_point(p) for p in v),
}
_TYPE_WORDS = {"int": "a whole number", "float": "a number", "str": "a text", "bool": "true or false",
               "point": "a point [x, y]", "points": "a list of points [[x, y], ...] (1 to 1000)"}


def check_spec(spec: Any) -> dict[str, Any]:
    """Validate one advertised task description; return it normalised.

    Raises :class:`FieldError` naming what is wrong.
    """
    if type(spec) is not dict:
        raise FieldError("each advertised task must be a map with 'name' and 'args'")
    name = spec.get("name")
    if type(name) is not str or not name or len(name) > 64:
        raise FieldError("an advertised task needs a 'name' of 1 to 64 characters")
    args = spec.get("args", [])
    if type(args) is not list or len(args) > MAX_ARGS:
        raise FieldError(f"task {name!r}: 'args' must be a list of at most {MAX_ARGS} argument descriptions")
    clean_args = []
    for i, a in enumerate(args):
        if type(a) is not dict or type(a.get("name")) is not str or a.get("type") not in ARG_TYPES:
            raise FieldError(
                f"task {name!r}: argument {i + 1} needs a 'name' and a 'type' among {', '.join(ARG_TYPES)}")
        clean_args.append({"name": a["name"], "type": a["type"],
                           "description": str(a.get("description", ""))[:200]})
    return {"name": name, "description": str(spec.get("description", ""))[:500], "args": clean_args}


def check_specs(specs: Any) -> dict[str, dict[str, Any]]:
    """Validate a list of advertised tasks; return them by name."""
    if type(specs) is not list or len(specs) > MAX_TASKS_ADVERTISED:
        raise FieldError(f"'tasks' must be a list of at most {MAX_TASKS_ADVERTISED} task descriptions")
    out: dict[str, dict[str, Any]] = {}
    for s in specs:
        clean = check_spec(s)
        out[clean["name"]] = clean
    return out


def signature(spec: dict[str, Any]) -> str:
    """A one-line human signature such as ``goTo(x: int, y: int)``."""
    return f"{spec['name']}({', '.join(a['name'] + ': ' + a['type'] for a in spec.get('args') or ())})"


def check_args(spec: dict[str, Any], args: list[Any]) -> list[Any]:
    """Check call arguments against a task description; raise :class:`BadTaskError` if they do not fit."""
    want = spec["args"]
    if type(args) not in (list, tuple):
        raise BadTaskError(f"arguments of {spec['name']} must be a list, as in {signature(spec)}")
    if len(args) != len(want):
        raise BadTaskError(
            f"{spec['name']} takes {len(want)} argument(s), got {len(args)}: use {signature(spec)}")
    out = []
    for a, value in zip(want, args):
        if a["type"] == "int" and type(value) is float and value.is_integer():
            value = int(value)  # 3.0 means 3
        if not _CHECKS[a["type"]](value):
            raise BadTaskError(
                f"argument {a['name']!r} of {spec['name']} must be {_TYPE_WORDS[a['type']]}, got {value!r:.40}")
        out.append(value)
    return out


def find_spec(specs: dict[str, dict[str, Any]], name: str, tag: int) -> dict[str, Any]:
    """Return the description of task ``name`` or raise a :class:`BadTaskError` listing the known ones."""
    spec = specs.get(name)
    if spec is None:
        known = ", ".join(sorted(specs)) or "none"
        raise BadTaskError(f"robot {tag} has no task {name!r}; its tasks are: {known}")
    return spec

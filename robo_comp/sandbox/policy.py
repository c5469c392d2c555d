"""The RestrictedPython policy for team code: compile step, guards and restricted globals.

Everything here runs inside the sandbox child process (see :mod:`robo_comp.sandbox.child`);
the parent never executes team code. The policy has two layers:

* **compile time** — :func:`compile_team` runs RestrictedPython's ``compile_restricted_exec``:
  no names or attributes starting with ``_``, no ``exec``/``eval``, no frame/generator
  introspection attributes, no ``async``, no ``try/except*``, no ``nonlocal``.
* **run time** — the guards installed into the module globals by :func:`make_globals`:
  ``_getattr_`` (refuses ``_`` names, a denylist of introspection attributes,
  ``str.format``/``format_map``, and any result that is a module, frame, code or traceback
  object), ``_write_`` (only team-class instances and builtin containers are writable),
  ``_getitem_``, ``_getiter_``, ``_inplacevar_``, ``_apply_``, the unpack guards, a capped
  ``print`` and an ``__import__`` that only knows the namespaces built here from pure functions.

The process boundary and rlimits (see the child) are the second line of defence.
"""
from __future__ import annotations

import ast as _ast
import builtins as _py_builtins
import heapq as _heapq
import math as _math
import operator as _operator
import random as _random
import types as _types
from dataclasses import dataclass
from typing import Any, Callable

from RestrictedPython import compile_restricted_exec
from RestrictedPython.Guards import (
    guarded_iter_unpack_sequence,
    guarded_unpack_sequence,
    safe_builtins,
)
from RestrictedPython.transformer import INSPECT_ATTRIBUTES, RestrictingNodeTransformer

from robo_comp.sandbox.explain import explain_compile_error
from robo_comp.sandbox import determinism as _determinism

__all__ = [
    "PolicyError", "TaskCancelled", "RobotError", "LimitExceeded", "Namespace",
    "compile_team", "make_globals", "guarded_getattr", "guarded_write", "DENIED_ATTRIBUTES",
    "ALLOWED_IMPORTS",
]


# --------------------------------------------------------------------------- exceptions
class TaskCancelled(BaseException):
    """Raised inside team code when the host interrupts or stops the task it runs."""


class RobotError(Exception):
    """Raised inside team code when the host refuses a robot-API call (bad args, blocked, ...)."""


class LimitExceeded(BaseException):
    """Raised inside team code when it breaks a sandbox limit (output, message size)."""


@dataclass
class PolicyError(Exception):
    """Team source that does not compile under the policy: ``rule`` names the broken rule."""

    line: int | None
    rule: str
    detail: str

    def __str__(self) -> str:  # pragma: no cover - trivial
        return f"line {self.line}: {self.rule}: {self.detail}"


# --------------------------------------------------------------------------- compile step
def _parse_line(err: str) -> tuple[int | None, str]:
    """Split RestrictedPython's ``'Line 3: text'`` error into ``(3, 'text')``."""
    if err.startswith("Line "):
        head, _, rest = err.partition(": ")
        try:
            return int(head[5:]), rest
        except ValueError:
            return None, rest
    return None, err


class _Transformer(RestrictingNodeTransformer):
    """RestrictedPython's transformer, with each class statement kept at its own line.

    RestrictedPython rebuilds every ``class`` statement from a parsed template to add
    ``metaclass=__metaclass__``, and the template's line (1) stayed on the new statement: an
    error raised by the class statement itself (a base that is not a class) was reported at line 1.
    """

    def visit_ClassDef(self, node: _ast.ClassDef) -> Any:
        """The class statement as RestrictedPython rewrites it, at the line of ``node``."""
        new = super().visit_ClassDef(node)
        if isinstance(new, _ast.ClassDef):
            _ast.copy_location(new, node)
            for kw in new.keywords:
                _ast.copy_location(kw, node)
                _ast.copy_location(kw.value, node)
        return new


def compile_team(source: str, filename: str) -> _types.CodeType:
    """Compile team ``source`` under the policy; raise :class:`PolicyError` on the first error.

    Syntax errors get rule ``syntax``; RestrictedPython refusals get rule ``policy``.
    """
    try:
        result = compile_restricted_exec(source, filename, policy=_Transformer)
    except RecursionError:
        raise PolicyError(None, "policy", "the code is nested too deeply for Python to read (brackets or "
                                          "blocks inside each other hundreds of times); flatten it") from None
    except (ValueError, TypeError, MemoryError) as exc:  # e.g. NUL bytes in source
        raise PolicyError(None, "syntax", f"Python cannot read this file ({str(exc)[:200]}); save it as "
                                          "plain UTF-8 text") from None
    if result.errors:
        lines = source.splitlines()
        parsed = sorted((_parse_line(e) for e in result.errors), key=lambda p: p[0] or 0)
        explained = [(line, *explain_compile_error(text, lines[line - 1] if line and 0 < line <= len(lines)
                                                   and (line != parsed[0][0] or i == 0) else None))
                     for i, (line, text) in enumerate(parsed)]
        line, rule, first = explained[0]
        others = [text if n == line else f"line {n}: {text}" for n, _, text in explained[1:3]]
        more = f" (and {len(parsed) - 3} more)" if len(parsed) > 3 else ""
        raise PolicyError(line, rule, "; also ".join([first, *others]) + more)
    assert result.code is not None
    return result.code


# --------------------------------------------------------------------------- namespaces
class Namespace:
    """A read-only bag of plain functions and constants exposed to team code (``math``, ...).

    It replaces real modules, which would leak ``sys`` and friends through their attributes.
    """

    __slots__ = ("_ns_name", "_ns_items")

    def __init__(self, name: str, items: dict[str, Any]) -> None:
        object.__setattr__(self, "_ns_name", name)
        object.__setattr__(self, "_ns_items", _types.MappingProxyType(dict(items)))

    def __getattribute__(self, name: str) -> Any:
        # the items first: ``robot.sense`` or ``math.sqrt`` is found at once, without the failed
        # lookup on the class (which makes and drops an AttributeError every time, a microsecond)
        try:
            return _ns_items(self)[name]
        except KeyError:
            pass
        try:
            return object.__getattribute__(self, name)
        except AttributeError:
            raise AttributeError(f"module {_ns_name(self)!r} has no attribute {name!r}") from None

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"module {self._ns_name!r} is read-only")

    def __delattr__(self, name: str) -> None:
        raise AttributeError(f"module {self._ns_name!r} is read-only")

    def __dir__(self) -> list[str]:
        return sorted(object.__getattribute__(self, "_ns_items"))

    def __repr__(self) -> str:
        return f"<module {self._ns_name!r} (sandbox)>"


_ns_items: Callable[[Namespace], Any] = Namespace._ns_items.__get__  # type: ignore[attr-defined]
_ns_name: Callable[[Namespace], str] = Namespace._ns_name.__get__  # type: ignore[attr-defined]


def _math_namespace() -> Namespace:
    names = [n for n in dir(_math) if not n.startswith("_")]
    return Namespace("math", {n: getattr(_math, n) for n in names})


def _random_namespace(start: int) -> Namespace:
    rng = _random.Random(start)

    def random() -> float:
        """A float in [0, 1)."""
        return rng.random()

    def uniform(a: float, b: float) -> float:
        """A float between a and b."""
        return rng.uniform(a, b)

    def randint(a: int, b: int) -> int:
        """An int in [a, b]."""
        return rng.randint(a, b)

    def randrange(*args: int) -> int:
        """Like range() but one random element."""
        return rng.randrange(*args)

    def choice(seq: Any) -> Any:
        """One random element of a non-empty sequence."""
        return rng.choice(seq)

    def shuffle(seq: list) -> None:
        """Shuffle a list in place."""
        if type(seq) is not list:
            raise TypeError("shuffle() needs a list")
        rng.shuffle(seq)

    def gauss(mu: float = 0.0, sigma: float = 1.0) -> float:
        """A normally distributed float."""
        return rng.gauss(mu, sigma)

    def seed(value: int | float | str | None = None) -> None:
        """Re-seed this sandbox's generator (it starts seeded per robot host; no value: that seed)."""
        if value is not None and type(value) not in (int, float, str):
            raise TypeError("seed() needs an int, float or str")
        rng.seed(start if value is None else value)  # never os.urandom: a match replays

    fns: list[Callable[..., Any]] = [random, uniform, randint, randrange, choice, shuffle, gauss, seed]
    return Namespace("random", {f.__name__: f for f in fns})


def _heapq_namespace() -> Namespace:
    return Namespace("heapq", {n: getattr(_heapq, n) for n in
                               ("heappush", "heappop", "heapify", "heappushpop", "heapreplace",
                                "nlargest", "nsmallest")})


ALLOWED_IMPORTS = ("math", "random", "heapq")
"""The only module names ``import`` accepts inside the sandbox."""


# --------------------------------------------------------------------------- guards
DENIED_ATTRIBUTES = frozenset(INSPECT_ATTRIBUTES) | frozenset({
    "format", "format_map",  # only denied on str; see guarded_getattr
    "mro", "gi_frame", "gi_code", "gi_yieldfrom", "cr_frame", "cr_code", "cr_await", "cr_origin",
    "ag_frame", "ag_code", "ag_await", "f_back", "f_globals", "f_locals", "f_builtins", "f_code",
    "f_trace", "tb_frame", "tb_next", "co_code", "func_globals", "func_code", "im_func", "im_self",
    "im_class", "func_closure",
})
_STR_ONLY = frozenset({"format", "format_map"})
_DENIED_RESULT_TYPES = (_types.ModuleType, _types.FrameType, _types.CodeType, _types.TracebackType)

def _team_metaclass(name: str, bases: tuple, namespace: dict, **kw: Any) -> type:
    """The ``__metaclass__`` RestrictedPython puts on every team class; records team classes."""
    if kw:
        raise TypeError("class keywords are not allowed in team code; write `class Name(Base):` without "
                        "`metaclass=` or other keywords")
    for base in bases:
        if not isinstance(base, type):
            raise TypeError("classes may only derive from classes; put a class in the brackets of "
                            "`class Name(Base):`")
    return _determinism.settle_class(_determinism.TeamType(name, bases, namespace))  # no addresses


def _is_team_class(cls: Any) -> bool:
    """True for a class of team code or one derived from it: only team code makes classes of
    type TeamType (3-argument ``type()`` and ``type()`` of a class are refused)."""
    return isinstance(cls, _determinism.TeamType)


def guarded_getattr(obj: Any, name: str, *default: Any) -> Any:
    """The ``_getattr_`` guard (also the sandbox's ``getattr``).

    Refuses ``_`` names, the introspection denylist, ``str.format``/``format_map`` (they reach
    attributes through format fields) and results that are modules, frames, code or tracebacks.
    """
    if type(name) is not str:
        raise TypeError("getattr() needs the attribute's name as text, e.g. getattr(obj, 'speed')")
    if name.startswith("_"):
        raise AttributeError(f'"{name}" is an invalid attribute name because it starts with "_" (Python\'s '
                             "internals are not reachable from team code); use the object's public methods instead")
    if name in DENIED_ATTRIBUTES:
        if name not in _STR_ONLY:
            raise AttributeError(f'"{name}" is a restricted attribute in the sandbox (it reaches the '
                                 "interpreter's frames and code); keep what you need in your own variables")
        if isinstance(obj, str) or (isinstance(obj, type) and issubclass(obj, str)):
            raise AttributeError(f'"str.{name}" is not allowed in the sandbox (its fields can reach private '
                                 'attributes); use an f-string instead, e.g. f"{x} cells"')
    if default:
        value = getattr(obj, name, default[0])
    else:
        value = getattr(obj, name)
    if isinstance(value, _DENIED_RESULT_TYPES):
        raise AttributeError(f'"{name}" leads to an interpreter object (a module, frame or code object), '
                             "refused in the sandbox; use the values you need directly")
    return value


class _ReadOnlyProxy:
    """What ``_write_`` returns for objects team code may not change: every write fails."""

    __slots__ = ("_ro_what",)

    def __init__(self, what: str) -> None:
        object.__setattr__(self, "_ro_what", what)

    def _refuse(self, *args: Any) -> None:
        raise TypeError(f"{object.__getattribute__(self, '_ro_what')} is read-only in the sandbox; keep your "
                        "own state in variables, lists, dicts or objects of your own classes")

    __setattr__ = __delattr__ = __setitem__ = __delitem__ = _refuse


_WRITABLE_TYPES = (list, dict, bytearray, set)


def guarded_write(obj: Any) -> Any:
    """The ``_write_`` guard: team-class instances (and team classes), lists, dicts, sets and
    bytearrays may be changed; modules, functions, builtins and the robot API may not."""
    tp = type(obj)
    if tp in _WRITABLE_TYPES or _is_team_class(tp):
        return obj
    if isinstance(obj, type) and _is_team_class(obj):
        return obj
    return _ReadOnlyProxy(f"a {tp.__name__!s} object")


def _guarded_setattr(obj: Any, name: str, value: Any) -> None:
    """The sandbox's ``setattr``: the ``_write_`` rules plus no ``_`` names."""
    if type(name) is not str or name.startswith("_"):
        raise AttributeError(f'"{name}" is an invalid attribute name for setattr(); give the name as text '
                             'that does not start with "_"')
    setattr(guarded_write(obj), name, value)


def _guarded_delattr(obj: Any, name: str) -> None:
    """The sandbox's ``delattr``."""
    if type(name) is not str or name.startswith("_"):
        raise AttributeError(f'"{name}" is an invalid attribute name for delattr(); give the name as text '
                             'that does not start with "_"')
    delattr(guarded_write(obj), name)


def _guarded_hasattr(obj: Any, name: str) -> bool:
    """The sandbox's ``hasattr`` (goes through the getattr guard)."""
    try:
        guarded_getattr(obj, name)
    except AttributeError:
        return False
    return True


def _getitem(obj: Any, key: Any) -> Any:
    """The ``_getitem_`` guard: plain subscription (no object reachable here is privileged)."""
    if isinstance(obj, (Namespace, _ReadOnlyProxy)):
        raise TypeError("namespace objects (math, random, heapq) are not subscriptable; use their "
                        "attributes, e.g. math.sqrt(2), not math['sqrt']")
    return obj[key]


_INPLACE_OPS: dict[str, Callable[[Any, Any], Any]] = {
    "+=": _operator.iadd, "-=": _operator.isub, "*=": _operator.imul, "/=": _operator.itruediv,
    "//=": _operator.ifloordiv, "%=": _operator.imod, "**=": _operator.ipow,
    "<<=": _operator.ilshift, ">>=": _operator.irshift, "&=": _operator.iand,
    "|=": _operator.ior, "^=": _operator.ixor, "@=": _operator.imatmul,
}


def _inplacevar(op: str, x: Any, y: Any) -> Any:
    """The ``_inplacevar_`` guard for ``x op= y`` on names."""
    fn = _INPLACE_OPS.get(op)
    if fn is None:
        raise SyntaxError(f"operator {op} is not allowed in team code; write it out: x = x {op[:-1]} y")
    return fn(x, y)


def _apply(func: Any, *args: Any, **kwargs: Any) -> Any:
    """The ``_apply_`` hook for calls with ``*args``/``**kwargs``."""
    return func(*args, **kwargs)


def _no_type(*args: Any) -> Any:
    """``type(x)`` is allowed (returns the class); the 3-argument form is refused, and so is
    ``type(cls)`` of a class (it would hand out the real metaclass, i.e. 3-argument ``type``)."""
    if len(args) != 1:
        raise TypeError("type() with 3 arguments (building classes) is not allowed in the sandbox; write a "
                        "`class Name:` statement instead")
    t = type(args[0])
    if issubclass(t, type):
        raise TypeError("type() of a class (the metaclass) is not available in the sandbox; compare classes "
                        "directly, e.g. isinstance(x, Cell) or cls is Cell")
    return t


# --------------------------------------------------------------------------- print
class _PrintFactory:
    """Builds the ``_print_`` collector; output goes to ``sink(text)`` (which enforces caps)."""

    def __init__(self, sink: Callable[[str], None]) -> None:
        self._sink = sink

    def __call__(self, _getattr_: Any = None) -> "_Printer":
        return _Printer(self._sink)


class _Printer:
    __slots__ = ("_sink", "_txt")

    def __init__(self, sink: Callable[[str], None]) -> None:
        self._sink = sink
        self._txt: list[str] = []

    def _call_print(self, *objects: Any, sep: Any = " ", end: Any = "\n", file: Any = None,
                    flush: bool = False) -> None:
        if file is not None:
            raise TypeError("print(file=...) is not allowed in the sandbox: print() writes to your team's log; "
                            "leave out file=")
        if sep is None:
            sep = " "
        if end is None:
            end = "\n"
        if type(sep) is not str or type(end) is not str:
            raise TypeError("print()'s sep and end must be text; write e.g. print(a, b, sep=', ')")
        text = sep.join(str(o) for o in objects) + end
        self._sink(text)

    def __call__(self) -> str:  # the ``printed`` name: we send output live, nothing collected
        return ""


# --------------------------------------------------------------------------- globals
_SAFE_EXTRA = {
    # Iteration helpers RestrictedPython leaves out only because they bypass Zope's _getiter_;
    # our _getiter_ is plain iter() (nothing reachable needs per-item security).
    name: getattr(_py_builtins, name)
    for name in ("all", "any", "enumerate", "filter", "map", "max", "min", "sum", "zip", "sorted",
                 "reversed", "list", "tuple", "dict", "set", "frozenset", "bytes", "iter", "next",
                 "object", "property", "staticmethod", "classmethod", "super", "format", "ascii",
                 "bin", "NotImplemented", "StopAsyncIteration", "RecursionError", "TimeoutError",
                 "ConnectionError", "PermissionError", "FileNotFoundError")
}
del _SAFE_EXTRA["format"]  # format(x, spec) is harmless but pointless; keep the surface small


def make_builtins(*, importer: Callable[..., Any], print_sink: Callable[[str], None]) -> dict:
    """A fresh builtins dict for one team module (never shared with another module)."""
    b: dict[str, Any] = {}
    b.update(safe_builtins)
    for name in ("setattr", "delattr", "_getattr_"):
        b.pop(name, None)
    b.update(_SAFE_EXTRA)
    b.update({
        "__build_class__": _py_builtins.__build_class__,
        "__import__": importer,
        "getattr": guarded_getattr,
        "setattr": _guarded_setattr,
        "delattr": _guarded_delattr,
        "hasattr": _guarded_hasattr,
        "type": _no_type,
        "TaskCancelled": TaskCancelled,
        "RobotError": RobotError,
        "LimitExceeded": LimitExceeded,
    })
    b.update(_determinism.BUILTINS)  # id, hash, repr, ascii without per-process entropy
    return b


class Policy:
    """Per-child policy state: the immutable namespaces and the print sink.

    ``seed`` seeds the sandbox's ``random``; ``print_sink(text)`` receives print output.
    """

    def __init__(self, seed: int, print_sink: Callable[[str], None]) -> None:
        self.modules = {
            "math": _math_namespace(),
            "random": _random_namespace(seed),
            "heapq": _heapq_namespace(),
        }
        self.print_sink = print_sink
        self._printer = _PrintFactory(print_sink)

    def importer(self, name: str, globals: Any = None, locals: Any = None, fromlist: Any = (),
                 level: int = 0) -> Namespace:
        """The sandbox's ``__import__``: only :data:`ALLOWED_IMPORTS`, as read-only namespaces."""
        if level != 0 or type(name) is not str or name not in self.modules:
            raise ImportError(f"import of {name!r} is not allowed in the sandbox; import only "
                              f"{', '.join(ALLOWED_IMPORTS)}, and reach the robot through your tasks' "
                              "`robot` argument")
        return self.modules[name]

    def make_globals(self, module_name: str) -> dict[str, Any]:
        """Fresh restricted globals for one team module."""
        return {
            "__builtins__": make_builtins(importer=self.importer, print_sink=self.print_sink),
            "__name__": module_name,
            "__metaclass__": _team_metaclass,
            "_getattr_": guarded_getattr,
            "_getitem_": _getitem,
            "_getiter_": iter,
            "_write_": guarded_write,
            "_inplacevar_": _inplacevar,
            "_apply_": _apply,
            "_print_": self._printer,
            "_iter_unpack_sequence_": guarded_iter_unpack_sequence,
            "_unpack_sequence_": guarded_unpack_sequence,
        }


def make_globals(module_name: str, seed: int = 0,
                 print_sink: Callable[[str], None] = lambda text: None) -> dict[str, Any]:
    """Convenience: restricted globals from a throw-away :class:`Policy` (used by tests)."""
    return Policy(seed, print_sink).make_globals(module_name)

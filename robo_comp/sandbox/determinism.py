"""What team code sees of per-process entropy, made the same in every replay of a match.

A league match played again (a Ray retry, a failed match played later, a referee checking a
result) must give the same event log to the byte, however the team code is written. Python
gives a program three kinds of per-process entropy; the sandbox closes each:

* **string hashing** (``hash()`` of ``str``/``bytes``, and the order of their sets): the parent
  starts the child with ``PYTHONHASHSEED`` derived from the match seed
  (:meth:`robo_comp.sandbox.parent.Sandbox.start`);
* **memory addresses**: CPython shows an object's address in its default text
  (``<function f at 0x7f…>``, reached through ``repr()``, ``str()``, f-strings, ``%``, the text
  of a list holding it, error messages) and hashes by it (``hash()``, so the order a set or
  frozenset of such objects is walked in). :func:`seal`, run first thing in every sandbox
  child, replaces these at the level of the types themselves, so every path to them is
  covered: an object that would show its address shows a serial number instead
  (``<function f #12>``), handed out in the order the child first needs one (team code runs
  in the same order in every replay, so it gets the same numbers), and hashes by it; classes,
  built-in functions and ``None``-like singletons hash by name. ``id`` is not offered.
  Text the child prints is scrubbed of `` at 0x…`` as a second line of defence;
* **the OS's random numbers**: the sandbox's ``random`` is seeded from the match seed, and
  ``random.seed()`` without a value goes back to that seed instead of reading ``os.urandom``.

Time is not reachable (no ``time`` import; ``robot.sense()["time"]`` is the match clock).
docs/sandbox.md, "Determinism", lists every source and what is done to it.
"""
from __future__ import annotations

import _thread
import builtins as _py_builtins
import itertools
import re
import types as _types
import weakref
from collections.abc import Callable

#: An address as CPython shows it in a default repr.
_ADDRESS = re.compile(r" at 0x[0-9a-fA-F]+")


def scrub(text: str) -> str:
    """``text`` with every `` at 0x…`` address shown as `` at 0x?``."""
    return _ADDRESS.sub(" at 0x?", text) if " at 0x" in text else text


class _Serials:
    """Serial numbers for objects by identity, handed out in the order they are first asked
    for (deterministic when the team code is); an entry goes when its object does. Only
    objects that can be weakly referenced get one (a number must not keep its object alive)."""

    def __init__(self) -> None:
        self._next = itertools.count(1)
        self._by_id: dict[int, tuple[weakref.ref, int]] = {}
        self._lock = _thread.RLock()  # a new number is given once, whichever thread asks first

    def of(self, obj: object) -> int | None:
        """``obj``'s serial number; None if it cannot be weakly referenced."""
        key = _py_builtins.id(obj)
        entry = self._by_id.get(key)
        if entry is not None and entry[0]() is obj:
            return entry[1]
        with self._lock:
            entry = self._by_id.get(key)
            if entry is not None and entry[0]() is obj:
                return entry[1]
            try:
                ref = weakref.ref(obj, self._forget(key))
            except TypeError:
                return None
            n = next(self._next)
            self._by_id[key] = (ref, n)
            return n

    def _forget(self, key: int) -> Callable[[weakref.ref], None]:
        by_id = self._by_id

        def gone(ref: weakref.ref) -> None:
            held = by_id.get(key)
            if held is not None and held[0] is ref:
                del by_id[key]
        return gone


SERIALS = _Serials()


def _name_of(tp: type) -> str:
    """A type's name as CPython's default repr shows it (module-qualified outside builtins)."""
    module = tp.__module__
    return tp.__qualname__ if module == "builtins" else f"{module}.{tp.__qualname__}"


def _numbered(obj: object) -> str:
    n = SERIALS.of(obj)
    return "" if n is None else f" #{n}"


def _serial_hash(self: object) -> int:
    """The hash of an object Python would hash by its address: its serial number (by its
    type's name where it cannot have one; such objects are then all equal-hashed, which is
    slower in a big set but still the same in every replay)."""
    n = SERIALS.of(self)
    return _py_builtins.hash(("object", _name_of(type(self)))) if n is None else n


def _serial_repr(self: object) -> str:
    """``<module.Class object #7>``: the default repr, by serial number instead of address."""
    return f"<{_name_of(type(self))} object{_numbered(self)}>"


def _function_repr(self: _types.FunctionType) -> str:
    return f"<function {self.__qualname__}{_numbered(self)}>"


def _generator_repr(self: _types.GeneratorType) -> str:
    return f"<{type(self).__name__} object {self.__qualname__}{_numbered(self)}>"


def _builtin_repr(self: _types.BuiltinFunctionType) -> str:
    owner = self.__self__
    if owner is None or isinstance(owner, _types.ModuleType):
        return f"<built-in function {self.__name__}>"
    return f"<built-in method {self.__name__} of {_name_of(type(owner))} object>"


def _builtin_hash(self: _types.BuiltinFunctionType) -> int:
    # equal built-in methods have the same name (and the same owner): the name is a fit hash
    return _py_builtins.hash(("built-in", self.__module__, self.__qualname__))


def _method_hash(self: _types.MethodType) -> int:
    owner = SERIALS.of(self.__self__)
    return _py_builtins.hash(("method", _serial_hash(self.__self__) if owner is None else owner,
                              _py_builtins.hash(self.__func__)))


def _type_hash(self: type) -> int:
    return _py_builtins.hash(("type", self.__module__, self.__qualname__))


def _singleton_hash(self: object) -> int:
    return _py_builtins.hash(("singleton", type(self).__name__))


class TeamType(type):
    """The type of every team class: a class hashes by its serial number, not its address."""

    def __hash__(cls) -> int:
        n = SERIALS.of(cls)
        return _type_hash(cls) if n is None else n


def settle_class(cls: type) -> type:
    """Give a new team class a hash and a repr by serial number where it would use its
    address (it defines neither and inherits them from ``object``). A sealed child already
    does this for every class; this keeps team classes right in a child that is not."""
    if cls.__hash__ is object.__hash__:
        type.__setattr__(cls, "__hash__", _serial_hash)
    if cls.__repr__ is object.__repr__:
        type.__setattr__(cls, "__repr__", _serial_repr)
    return cls


# --------------------------------------------------------------------------- sealing
#: ``Py_TPFLAGS_IMMUTABLETYPE``: Python's own types refuse new attributes while it is set.
_IMMUTABLE = 1 << 8

#: What :func:`seal` puts on Python's own types: (type, attribute, replacement).
_SEALS: list[tuple[type, str, object]] = [
    (object, "__repr__", _serial_repr),
    (object, "__hash__", _serial_hash),
    (type, "__hash__", _type_hash),
    (type(None), "__hash__", _singleton_hash),
    (type(Ellipsis), "__hash__", _singleton_hash),
    (type(NotImplemented), "__hash__", _singleton_hash),
    (_types.FunctionType, "__repr__", _function_repr),
    (_types.GeneratorType, "__repr__", _generator_repr),
    (_types.CoroutineType, "__repr__", _generator_repr),
    (_types.AsyncGeneratorType, "__repr__", _generator_repr),
    (_types.BuiltinFunctionType, "__repr__", _builtin_repr),
    (_types.BuiltinFunctionType, "__hash__", _builtin_hash),
    (_types.MethodType, "__hash__", _method_hash),
]

_sealed = False


def _flags_offset() -> int:
    """Where ``tp_flags`` sits in a type object: the offset at which several types hold
    exactly their ``__flags__``."""
    import ctypes

    probes = (int, type, list, _types.FunctionType, object)
    for off in range(8, 512, ctypes.sizeof(ctypes.c_ulong)):
        if all(ctypes.c_ulong.from_address(_py_builtins.id(t) + off).value == t.__flags__ for t in probes):
            return off
    raise RuntimeError("the type layout of this Python is not known")


def _set_on(tp: type, name: str, value: object, offset: int) -> None:
    """``tp.name = value`` for one of Python's own types: its immutable flag is lifted for the
    assignment (which also updates the type's C slot and its subclasses'), then put back."""
    import ctypes

    flags = ctypes.c_ulong.from_address(_py_builtins.id(tp) + offset)
    was = flags.value & _IMMUTABLE
    flags.value &= ~_IMMUTABLE
    try:
        type.__setattr__(tp, name, value)
    finally:
        # only this bit: the assignment changed others (the method cache's version tag)
        flags.value |= was


def seal() -> None:
    """Make every object that Python would show or hash by its memory address show and hash
    by a serial number (or a name) instead, in this process, for good.

    Run first thing in a sandbox child, before the modules it needs are imported: a dict
    keyed by such objects built before keeps the old hashes (a cache then misses once; every
    dict and set made after is consistent). Raises RuntimeError, and changes nothing, where
    this Python's type objects are not laid out as expected; the check afterwards raises it
    where the change did not take."""
    global _sealed
    if _sealed:
        return
    offset = _flags_offset()
    for tp, name, value in _SEALS:
        _set_on(tp, name, value, offset)
    _sealed = True

    def probe() -> None:
        pass
    text = f"{probe} {object()} {probe!r} {[].append} {iter(())}" + "%s" % (probe,)
    if "0x" in text or hash(probe) != SERIALS.of(probe) or hash(int) != _type_hash(int):
        raise RuntimeError(f"sealing did not take: {text}")


def seal_child() -> None:
    """:func:`seal` for a sandbox child's start: a failure is kept (see :func:`sealed`), not
    raised; a replayable child then refuses to run, the others show scrubbed text."""
    global _seal_error
    try:
        seal()
    except Exception as exc:  # an unknown Python: the child decides (see child.main)
        _seal_error = str(exc) or type(exc).__name__


_seal_error: str | None = None


def sealed() -> bool:
    """True once :func:`seal` has run in this process."""
    return _sealed


def _by_address(obj: object) -> bool:
    """True if ``hash(obj)`` would be the object's address (or contain one) in a child that is
    not sealed."""
    tp = type(obj)
    if tp in (tuple, frozenset):
        return any(_by_address(x) for x in obj)  # type: ignore[attr-defined]
    h = getattr(tp, "__hash__", None)
    return h is object.__hash__ or h is type.__hash__ or (
        tp.__name__ in ("method", "builtin_function_or_method", "method-wrapper") and tp.__module__ == "builtins")


def safe_hash(obj: object) -> int:
    """``hash(obj)``. In a sealed child every hash is free of addresses; in one that is not,
    an object hashed by its address is refused (its hash would change every run)."""
    if not _sealed and _by_address(obj):
        raise TypeError(f"hash() of a {type(obj).__name__} is its memory address, which changes every time "
                        "the match is played; hash numbers, text, tuples of them or your own classes")
    return _py_builtins.hash(obj)


def safe_repr(obj: object) -> str:
    """``repr(obj)`` without memory addresses."""
    return scrub(_py_builtins.repr(obj))


def safe_ascii(obj: object) -> str:
    """``ascii(obj)`` without memory addresses."""
    return scrub(_py_builtins.ascii(obj))


def no_id(obj: object = None) -> int:
    """``id()`` is not offered: it is a memory address, different every time a match is played."""
    raise NameError("id() is not available in the sandbox: it is a memory address and would differ every "
                    "time the match is played; compare objects with `is`, or number them yourself")


#: The sandbox's replacements for builtins that show per-process entropy.
BUILTINS: dict[str, object] = {"id": no_id, "hash": safe_hash, "repr": safe_repr, "ascii": safe_ascii}

__all__ = ["BUILTINS", "SERIALS", "TeamType", "no_id", "safe_ascii", "safe_hash", "safe_repr", "scrub", "seal",
           "seal_child", "sealed", "settle_class"]

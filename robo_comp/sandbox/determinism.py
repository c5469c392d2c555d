"""What team code sees of per-process entropy, made the same in every replay of a match.

A league match played again (a Ray retry, a failed match played later, a referee checking a
result) must give the same event log to the byte, however the team code is written. Python
gives a program three kinds of per-process entropy; the sandbox closes each:

* **string hashing** (``hash()`` of ``str``/``bytes``, and the order of their sets): the parent
  starts the child with ``PYTHONHASHSEED`` derived from the match seed
  (:meth:`robo_comp.sandbox.parent.Sandbox.start`);
* **memory addresses** (``id()``, the default ``hash()`` of objects, ``repr()`` of functions
  and plain objects, the order of sets of such objects): ``id`` is not offered, the sandbox's
  ``hash`` refuses objects hashed by address, ``repr``/``ascii`` and printed text show
  ``at 0x…`` as ``at 0x?``, and every team class (and every instance of one) hashes and
  shows by a serial number given in the order team code first asks for it (:func:`settle_class`).
  A replayable child also runs without address randomisation (ASLR), so what is left — an
  f-string or ``%`` of a *function* or *generator*, a set of functions — repeats in practice,
  but is not promised (docs/sandbox.md, "Determinism");
* **the OS's random numbers**: the sandbox's ``random`` is seeded from the match seed, and
  ``random.seed()`` without a value goes back to that seed instead of reading ``os.urandom``.

Time is not reachable (no ``time`` import; ``robot.sense()["time"]`` is the match clock).
"""
from __future__ import annotations

import builtins as _py_builtins
import itertools
import re
import weakref
from typing import Any

#: An address as CPython shows it in a default repr.
_ADDRESS = re.compile(r" at 0x[0-9a-fA-F]+")


def scrub(text: str) -> str:
    """``text`` with every `` at 0x…`` address shown as `` at 0x?``."""
    return _ADDRESS.sub(" at 0x?", text) if " at 0x" in text else text


class _Serials:
    """Serial numbers for objects by identity, handed out in the order they are first asked
    for (deterministic when the team code is); an entry goes when its object does."""

    def __init__(self) -> None:
        self._next = itertools.count(1)
        self._by_id: dict[int, tuple[Any, int]] = {}

    def of(self, obj: Any) -> int:
        key = _py_builtins.id(obj)
        entry = self._by_id.get(key)
        if entry is not None and entry[0]() is obj:
            return int(entry[1])
        n = next(self._next)

        def gone(ref: Any, key: int = key) -> None:
            held = self._by_id.get(key)
            if held is not None and held[0] is ref:
                del self._by_id[key]

        try:
            self._by_id[key] = (weakref.ref(obj, gone), n)
        except TypeError:  # not weak-referenceable (a class with __slots__): keep it
            self._by_id[key] = ((lambda o=obj: o), n)
        return n


SERIALS = _Serials()


def _serial_hash(self: Any) -> int:
    return SERIALS.of(self)


def _serial_repr(self: Any) -> str:
    cls = type(self)
    return f"<{cls.__module__}.{cls.__qualname__} object #{SERIALS.of(self)}>"


class TeamType(type):
    """The type of every team class: a class hashes by its serial number, not its address."""

    def __hash__(cls) -> int:
        return SERIALS.of(cls)


def settle_class(cls: type) -> type:
    """Give a new team class a hash and a repr by serial number where it would use its
    address (it defines neither and inherits them from ``object``)."""
    if cls.__hash__ is object.__hash__:
        type.__setattr__(cls, "__hash__", _serial_hash)
    if cls.__repr__ is object.__repr__:
        type.__setattr__(cls, "__repr__", _serial_repr)
    return cls


def _by_address(obj: Any) -> bool:
    """True if ``hash(obj)`` would be the object's address (or contain one)."""
    tp = type(obj)
    if tp in (tuple, frozenset):
        return any(_by_address(x) for x in obj)
    h = getattr(tp, "__hash__", None)
    return h is object.__hash__ or h is type.__hash__ or (
        tp.__name__ in ("method", "builtin_function_or_method", "method-wrapper") and tp.__module__ == "builtins")


def safe_hash(obj: Any) -> int:
    """``hash(obj)``, refused for an object hashed by its address (it would change every run)."""
    if _by_address(obj):
        raise TypeError(f"hash() of a {type(obj).__name__} is its memory address, which changes every time "
                        "the match is played; hash numbers, text, tuples of them or your own classes")
    return _py_builtins.hash(obj)


def safe_repr(obj: Any) -> str:
    """``repr(obj)`` without memory addresses."""
    return scrub(_py_builtins.repr(obj))


def safe_ascii(obj: Any) -> str:
    """``ascii(obj)`` without memory addresses."""
    return scrub(_py_builtins.ascii(obj))


def no_id(obj: Any = None) -> int:
    """``id()`` is not offered: it is a memory address, different every time a match is played."""
    raise NameError("id() is not available in the sandbox: it is a memory address and would differ every "
                    "time the match is played; compare objects with `is`, or number them yourself")


#: The sandbox's replacements for builtins that show per-process entropy.
BUILTINS: dict[str, Any] = {"id": no_id, "hash": safe_hash, "repr": safe_repr, "ascii": safe_ascii}

__all__ = ["BUILTINS", "SERIALS", "TeamType", "no_id", "safe_ascii", "safe_hash", "safe_repr", "scrub",
           "settle_class"]

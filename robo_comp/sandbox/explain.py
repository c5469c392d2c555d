"""The policy's refusals in a student's words.

RestrictedPython says what its compiler refused in its own terms ("TryStar statements are not
allowed", "AsyncFunctionDef statements are not allowed"). A student wrote ``except*`` or
``async def``. :func:`explain_compile_error` turns each refusal into one sentence that quotes the
code the student wrote, says what is not allowed in team code, and what to write instead; the
caller puts the file and line in front (``explorer.py:12: ...``).
"""
from __future__ import annotations

import re

#: The longest piece of a source line quoted in a message.
QUOTE_CHARS = 60

# (RestrictedPython's text, what the student reads): ``{0}`` is the first group of the pattern.
_RULES: list[tuple[str, str]] = [
    (r'"(_\w*)" is an invalid variable name because it starts with "_"',
     "names that start with an underscore (`{0}`) are kept for Python itself and not allowed in team code "
     "(of the special methods only __init__, __eq__, __lt__ and their like may be defined in a class); "
     "rename it without the leading `_`"),
    (r'"(_\w*)" is an invalid attribute name because it starts with "_"',
     "attributes that start with an underscore (`.{0}`) are Python's internals and not allowed in team code; "
     "use the object's public methods, and name your own attributes without a leading `_`"),
    (r'"(\w+)" is an invalid (?:variable|attribute) name because it ends with "__roles__"',
     "names ending in `__roles__` (`{0}`) are reserved by the sandbox; choose another name"),
    (r'"(builtins)" is a reserved name',
     "`{0}` is reserved in the sandbox and cannot be imported or named; call the built-in functions "
     "directly (len, min, max, sorted, ...) and import only math, random or heapq"),
    (r'"(print|printed)" is a reserved name',
     "`{0}` is the sandbox's own name for printing and cannot be defined or assigned; "
     "choose another name for your function or variable"),
    (r'"(\w+)" is a reserved name',
     "`{0}` is a reserved name in the sandbox; choose another name"),
    (r'"(\w+)" is a restricted name, that is forbidden to access',
     "`.{0}` reaches into the interpreter's frames and code objects and is not allowed in team code; "
     "keep what you need in your own variables, lists and dicts"),
    (r"Exec calls are not allowed",
     "`exec(...)` runs text as code and is not allowed in team code; write the code itself "
     "(to pick a function by name, keep the functions in a dict)"),
    (r"Eval calls are not allowed",
     "`eval(...)` runs text as code and is not allowed in team code; compute the value directly "
     "(for numbers in text use int() or float())"),
    (r"TryStar statements are not allowed",
     "`except*` (exception groups) is not allowed in team code; catch errors with a plain "
     "`except SomeError:`"),
    (r"Nonlocal statements are not allowed",
     "`nonlocal` is not allowed in team code; keep shared state in a dict, a list or an object of "
     "your own class, or return the new value"),
    (r"AsyncFunctionDef statements are not allowed",
     "async functions are not allowed in team code; write a plain `def` (robot calls already wait "
     "for their answers, and each robot's task runs on its own)"),
    (r"(?:Await|AsyncFor|AsyncWith) statements are not allowed",
     "`await`, `async for` and `async with` are not allowed in team code; use plain calls, `for` and `with`"),
    (r'"\*" imports are not allowed',
     "`import *` is not allowed in team code; import the names you use, e.g. `from math import sqrt, pi`"),
    (r"Lazy import statements are not allowed",
     "lazy imports are not allowed in team code; use a plain `import math` at the top of the file"),
    (r"Unpacking in comprehensions is not allowed",
     "unpacking (`*x`) inside a comprehension is not allowed in team code; build the list with a "
     "`for` loop and `extend`"),
    (r"Augmented assignment of attributes is not allowed",
     "`+=` and the like on an attribute (`obj.count += 1`) are not allowed in team code; "
     "write it out: `obj.count = obj.count + 1`"),
    (r"Augmented assignment of object items and slices is not allowed",
     "`+=` and the like on an item (`seen[cell] += 1`) are not allowed in team code; "
     "write it out: `seen[cell] = seen[cell] + 1`"),
    (r'The keyword argument "metaclass" is not allowed',
     "`metaclass=` is not allowed in team code; write a plain `class Name:` or `class Name(Base):`"),
    (r"Assignment expressions are only allowed for simple targets",
     "`:=` may only assign to a plain name in team code; assign to a name first, then store it"),
    (r"Match statements are not allowed",
     "`match`/`case` is not allowed in team code; use `if`/`elif`/`else`"),
    (r"TypeAlias statements are not allowed",
     "`type X = ...` is not allowed in team code; write a plain assignment `X = ...`"),
    (r"(\w+) statements are not allowed",
     "this kind of statement ({0}) is not allowed in team code; write it with plain statements "
     "(def, class, if, for, while, try/except, return)"),
]
_COMPILED: list[tuple[re.Pattern[str], str]] = [(re.compile(p), t) for p, t in _RULES]

_SYNTAX = re.compile(r"(SyntaxError|IndentationError|TabError): (.*?)(?: at statement: .*)?$", re.S)


def quote(code: str | None) -> str:
    """A source line as a message quotes it: stripped, shortened, in backquotes."""
    text = " ".join((code or "").split())
    if len(text) > QUOTE_CHARS:
        text = text[:QUOTE_CHARS - 1] + "…"
    return f"`{text}`" if text else ""


def explain_compile_error(text: str, code: str | None) -> tuple[str, str]:
    """``(rule, sentence)`` for one RestrictedPython error ``text`` (its ``Line N:`` removed)
    about the source line ``code``: rule ``syntax`` or ``policy``."""
    q = quote(code)
    lead = f"{q}: " if q else ""
    m = _SYNTAX.search(text)
    if m:
        kind, why = m.group(1), m.group(2).strip()
        hint = ("check the indentation of this line and the one before (use 4 spaces, never tabs)"
                if kind != "SyntaxError" else
                "check this line and the one before it for a missing `:`, bracket, quote or comma")
        return "syntax", f"{lead}Python cannot read this ({why}); {hint}"
    for pattern, sentence in _COMPILED:
        m = pattern.search(text)
        if m:
            return "policy", lead + sentence.format(*m.groups())
    return "policy", f"{lead}{text.rstrip('.')}; see docs/sandbox.md for what team code may do"

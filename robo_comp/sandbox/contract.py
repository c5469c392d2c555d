"""The checked init contract for uploaded team modules (extensions and code).

An upload is accepted only if every step passes, in this order (the ``rule`` names appear in
error messages as ``file:line: rule: detail``):

``filename``  the file name is ``[A-Za-z0-9_.-]{1,64}`` ending in ``.py``;
``size``      the source is UTF-8 text of at most ``MAX_SOURCE_BYTES``;
``syntax``    it parses;
``policy``    it compiles under the RestrictedPython policy (:mod:`.restricted`), and every
              ``import`` in it, at top level or inside a function, names an allowed module
              (:data:`robo_comp.sandbox.policy.ALLOWED_IMPORTS`);
``manifest``  a top-level ``MANIFEST = {...}`` literal exists and has the strict shape below;
``signature`` every declared task has a top-level ``def task(robot, <args in order>)`` and an
              optional ``def init(robot)`` takes exactly ``robot``;
``module``    the module body runs without error (inside the sandbox, time-limited);
``init``      ``init(robot)`` returns within the init time limit;
``conflict``  no other loaded module (of another name) already provides one of the tasks, and
              an ``extension`` does not reuse a built-in task name (that needs ``kind: code``).

Manifest shape::

    MANIFEST = {
        "name": "square", "version": "1.0", "kind": "extension",   # or "code"
        "description": "optional text",
        "tasks": {"square": {"description": "...",
                             "args": [{"name": "side", "type": "int", "description": "..."}]}},
    }

The static steps (everything up to ``signature``) read the AST only; nothing is executed.
They run inside the sandbox child like the rest, so hostile source never touches the host.
"""
from __future__ import annotations

import ast
import hashlib
import re
from dataclasses import dataclass, field
from typing import Any

from robo_comp.errors import UploadError

__all__ = [
    "ARG_TYPES", "BUILTIN_TASKS", "MAX_SOURCE_BYTES", "ContractError", "ModuleInfo",
    "check_filename", "check_source", "read_manifest", "check_signatures", "check_task_args", "check_imports",
    "upload_error", "source_hash",
]

ARG_TYPES = ("int", "float", "str", "bool", "point", "points")
BUILTIN_TASKS = ("goTo", "followPath", "examineArea")
"""Task names built into every robot; an ``extension`` may not reuse them, ``code`` may."""
MAX_SOURCE_BYTES = 60_000
MAX_TASKS = 32
MAX_ARGS = 16
_FILE_RE = re.compile(r"[A-Za-z0-9_.\-]{1,64}")
_NAME_RE = re.compile(r"[a-z][a-z0-9_]{0,39}")
_TASK_RE = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,39}")
_VERSION_RE = re.compile(r"[0-9A-Za-z.+\-]{1,20}")
_TOP_KEYS = {"name", "version", "kind", "tasks"}
_OPT_KEYS = {"description"}


@dataclass
class ContractError(Exception):
    """One broken contract rule, with the line it concerns (if any)."""

    rule: str
    detail: str
    line: int | None = None

    def __str__(self) -> str:
        return f"{self.rule}: {self.detail}"


def upload_error(filename: str, rule: str, detail: str, line: int | None = None) -> UploadError:
    """The :class:`UploadError` for a broken rule: ``'file:line: rule: detail'``."""
    where = f"{filename}:{line}" if line else filename
    return UploadError(f"{where}: {rule}: {detail}", file=filename, line=line, rule=rule)


@dataclass
class ModuleInfo:
    """A loaded module as the parent reports it: identity, kind and advertised tasks."""

    name: str
    version: str
    kind: str
    file: str
    sha256: str
    tasks: dict[str, dict[str, Any]] = field(default_factory=dict)
    description: str = ""
    replaces: list[str] = field(default_factory=list)

    def plain(self) -> dict[str, Any]:
        """The module as plain data (for the wire or a console)."""
        return {"name": self.name, "version": self.version, "kind": self.kind, "file": self.file,
                "sha256": self.sha256, "tasks": self.tasks, "description": self.description,
                "replaces": list(self.replaces)}


def source_hash(source: str) -> str:
    """Hex SHA-256 of the UTF-8 source (what ``modules()`` reports)."""
    return hashlib.sha256(source.encode("utf-8", "surrogatepass")).hexdigest()


def check_filename(filename: Any) -> str:
    """Rule ``filename``: a short plain file name ending in ``.py``."""
    if type(filename) is not str or not _FILE_RE.fullmatch(filename) or not filename.endswith(".py") \
            or filename.startswith("."):
        raise ContractError("filename", f"{str(filename)[:80]!r} is not a plain file name "
                                        "of at most 64 characters ending in .py")
    return filename


def check_source(source: Any) -> str:
    """Rule ``size``: text (str, or UTF-8 bytes) of at most :data:`MAX_SOURCE_BYTES`."""
    if isinstance(source, (bytes, bytearray)):
        if len(source) > MAX_SOURCE_BYTES:
            raise ContractError("size", f"the source is {len(source)} bytes, the limit is "
                                        f"{MAX_SOURCE_BYTES}")
        try:
            source = bytes(source).decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ContractError("size", f"the source is not UTF-8 text ({exc.reason} at byte "
                                        f"{exc.start})") from None
    if type(source) is not str:
        raise ContractError("size", "the source must be text")
    n = len(source.encode("utf-8", "surrogatepass"))
    if n > MAX_SOURCE_BYTES:
        raise ContractError("size", f"the source is {n} bytes, the limit is {MAX_SOURCE_BYTES}")
    if "\x00" in source:
        raise ContractError("syntax", "the source contains a NUL character")
    return source


def _manifest_node(tree: ast.Module) -> ast.expr:
    found = None
    for node in tree.body:
        targets: list[ast.expr] = []
        if isinstance(node, ast.Assign):
            targets = node.targets
        elif isinstance(node, (ast.AnnAssign, ast.AugAssign)):
            targets = [node.target]
        for t in targets:
            if isinstance(t, ast.Name) and t.id == "MANIFEST":
                if found is not None or not isinstance(node, ast.Assign):
                    raise ContractError("manifest", "MANIFEST must be assigned exactly once, "
                                                    "as MANIFEST = {...}", node.lineno)
                found = node.value
    if found is None:
        raise ContractError("manifest", "the module declares no MANIFEST = {...}", 1)
    return found


def _expect_keys(d: dict, required: set[str], optional: set[str], what: str, line: int) -> None:
    keys = set(d)
    bad = [k for k in d if type(k) is not str]
    if bad:
        raise ContractError("manifest", f"{what}: keys must be strings", line)
    missing = sorted(required - keys)
    if missing:
        raise ContractError("manifest", f"{what}: missing key(s) {', '.join(missing)}", line)
    extra = sorted(keys - required - optional)
    if extra:
        raise ContractError("manifest", f"{what}: unknown key(s) {', '.join(extra)}", line)


def _text(v: Any, what: str, line: int, limit: int = 200) -> str:
    if type(v) is not str or len(v) > limit:
        raise ContractError("manifest", f"{what} must be a text of at most {limit} characters",
                            line)
    return v


def read_manifest(tree: ast.Module) -> dict[str, Any]:
    """Rule ``manifest``: read ``MANIFEST`` statically (a literal) and validate it strictly.

    Returns the normalised manifest; tasks come back as ``{name: {"name", "description",
    "args"}}`` (the advertised-task shape of :mod:`robo_comp.protocol.taskspec`).
    """
    node = _manifest_node(tree)
    line = node.lineno
    try:
        m = ast.literal_eval(node)
    except (ValueError, TypeError, SyntaxError, MemoryError, RecursionError):
        raise ContractError("manifest", "MANIFEST must be a literal dict (no names, calls or "
                                        "expressions)", line) from None
    if type(m) is not dict:
        raise ContractError("manifest", "MANIFEST must be a dict", line)
    _expect_keys(m, _TOP_KEYS, _OPT_KEYS, "MANIFEST", line)
    name = m["name"]
    if type(name) is not str or not _NAME_RE.fullmatch(name):
        raise ContractError("manifest", "'name' must be lower-case letters, digits and _ "
                                        "(1-40, starting with a letter)", line)
    version = m["version"]
    if type(version) is not str or not _VERSION_RE.fullmatch(version):
        raise ContractError("manifest", "'version' must be a text such as \"1.0\" "
                                        "(1-20 of 0-9 A-Z a-z . + -)", line)
    kind = m["kind"]
    if kind not in ("extension", "code") or type(kind) is not str:
        raise ContractError("manifest", "'kind' must be \"extension\" or \"code\"", line)
    description = _text(m.get("description", ""), "'description'", line)
    tasks = m["tasks"]
    if type(tasks) is not dict or not tasks or len(tasks) > MAX_TASKS:
        raise ContractError("manifest", f"'tasks' must be a dict of 1 to {MAX_TASKS} tasks", line)
    out_tasks: dict[str, dict[str, Any]] = {}
    for tname, spec in tasks.items():
        if type(tname) is not str or not _TASK_RE.fullmatch(tname) or tname in ("init", "MANIFEST"):
            raise ContractError("manifest", f"task name {str(tname)[:40]!r} must be a letter then "
                                            "letters, digits or _ (at most 40; not init)", line)
        what = f"task {tname!r}"
        if type(spec) is not dict:
            raise ContractError("manifest", f"{what} must be a dict with 'args' and "
                                            "'description'", line)
        _expect_keys(spec, {"args"}, {"description"}, what, line)
        tdesc = _text(spec.get("description", ""), f"{what} 'description'", line)
        args = spec["args"]
        if type(args) is not list or len(args) > MAX_ARGS:
            raise ContractError("manifest", f"{what}: 'args' must be a list of at most {MAX_ARGS}",
                                line)
        seen: set[str] = set()
        out_args = []
        for i, a in enumerate(args):
            awhat = f"{what} argument {i + 1}"
            if type(a) is not dict:
                raise ContractError("manifest", f"{awhat} must be a dict with 'name', 'type' "
                                                "and 'description'", line)
            _expect_keys(a, {"name", "type"}, {"description"}, awhat, line)
            aname = a["name"]
            if type(aname) is not str or not aname.isidentifier() or aname.startswith("_") \
                    or aname == "robot" or aname in seen or len(aname) > 40:
                raise ContractError("manifest", f"{awhat}: 'name' {str(aname)[:40]!r} must be a "
                                                "unique identifier, not robot, not starting with _",
                                    line)
            seen.add(aname)
            if a["type"] not in ARG_TYPES or type(a["type"]) is not str:
                raise ContractError("manifest", f"{awhat} ({aname}): 'type' must be one of "
                                                f"{', '.join(ARG_TYPES)}", line)
            out_args.append({"name": aname, "type": a["type"],
                             "description": _text(a.get("description", ""),
                                                  f"{awhat} 'description'", line)})
        out_tasks[tname] = {"name": tname, "description": tdesc, "args": out_args}
    return {"name": name, "version": version, "kind": kind, "description": description,
            "tasks": out_tasks}


def _params(fn: ast.FunctionDef) -> tuple[list[str], str | None]:
    a = fn.args
    problem = None
    if a.posonlyargs or a.vararg or a.kwarg or a.kwonlyargs:
        problem = "no *args, **kwargs, keyword-only or positional-only parameters"
    elif a.defaults:
        problem = "no default values"
    return [p.arg for p in a.args], problem


def check_signatures(tree: ast.Module, manifest: dict[str, Any]) -> None:
    """Rule ``signature``: each task has ``def task(robot, <args>)`` at top level; ``init(robot)``.

    Functions defined more than once at top level are refused (the checked one must be the one
    that runs). The child re-checks the functions after running the module body.
    """
    defs: dict[str, ast.FunctionDef] = {}
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            if node.name in defs and (node.name in manifest["tasks"] or node.name == "init"):
                raise ContractError("signature", f"function {node.name!r} is defined twice",
                                    node.lineno)
            defs[node.name] = node
    for tname, spec in manifest["tasks"].items():
        want = ["robot"] + [a["name"] for a in spec["args"]]
        fn = defs.get(tname)
        if fn is None:
            raise ContractError("signature", f"task {tname!r} is declared in MANIFEST but there is "
                                             f"no top-level def {tname}({', '.join(want)})",
                                _manifest_node(tree).lineno)
        got, problem = _params(fn)
        if problem:
            raise ContractError("signature", f"def {tname}: {problem}", fn.lineno)
        if got != want:
            raise ContractError("signature", f"def {tname}({', '.join(got)}) does not match the "
                                             f"manifest; expected def {tname}({', '.join(want)})",
                                fn.lineno)
        if fn.decorator_list:
            raise ContractError("signature", f"def {tname}: task functions may not be decorated",
                                fn.lineno)
    init = defs.get("init")
    if init is not None:
        got, problem = _params(init)
        if problem or got != ["robot"] or init.decorator_list:
            raise ContractError("signature", "init must be declared as def init(robot)",
                                init.lineno)


def check_imports(tree: ast.Module) -> None:
    """Rule ``policy``: every ``import`` anywhere in the module (a function's too, which would
    otherwise fail only when the function first runs, in the match) names an allowed module."""
    from robo_comp.sandbox.policy import ALLOWED_IMPORTS

    for node in ast.walk(tree):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            names = ["." * node.level + (node.module or "")]
        for name in names:
            if name.split(".")[0] not in ALLOWED_IMPORTS or name.startswith("."):
                raise ContractError("policy", f"import of {name!r} is not allowed in the sandbox; import only "
                                              f"{', '.join(ALLOWED_IMPORTS)} (an import inside a function "
                                              "counts too)", getattr(node, "lineno", None))


def check_task_args(spec: dict[str, Any], args: Any) -> list[Any]:
    """Check call arguments against an advertised task; raise :class:`BadTaskError` if wrong."""
    from robo_comp.protocol.taskspec import check_args  # the core's own check (the parent's side only)

    return check_args(spec, args)

"""The tree keeps its shape (see docs/architecture.md), and every rule here can fail.

Read from the source with ast. Two graphs:

* modules: every import counts, also those inside functions and under ``if TYPE_CHECKING:``;
  no circle of modules anywhere in robo_comp/;
* packages (``robo_comp.X`` for each package or top-level module X): runtime imports only
  (``if TYPE_CHECKING:`` imports are types, as pytest's hookspecs take theirs); each package
  imports only what the table of docs/architecture.md lets it ("may import"), no circle of
  packages, and no UI imports another UI.

Each rule is checked on the real tree and shown to fail on a planted violation (a copy of the
graph with one import added), so that none of them passes whatever the tree holds.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent / "robo_comp"
DOC = ROOT.parent / "docs" / "architecture.md"
#: The user interfaces: none of them imports another, nothing below them imports one.
UIS = frozenset({"tui", "wall", "web"})
#: Folders of team code for the sandbox, not robo_comp's (the team template, the league's
#: reference teams): their modules are not part of the tree's shape.
TEAM_CODE = ("template", "reference")

ModGraph = dict[str, set[str]]
PkgGraph = dict[str, set[str]]


def _modules(root: Path = ROOT) -> dict[str, Path]:
    mods = {}
    for p in root.rglob("*.py"):
        if any(part in TEAM_CODE for part in p.relative_to(root).parts[:-1]) and p.name != "__init__.py":
            continue
        parts = p.relative_to(root.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        mods[name] = p
    return mods


def _type_only(tree: ast.AST) -> set[int]:
    """The ids of the nodes under ``if TYPE_CHECKING:``."""
    out: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If):
            t = node.test
            if (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
                    isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING"):
                for n in node.body:
                    out.update(id(m) for m in ast.walk(n))
    return out


def _graphs() -> tuple[ModGraph, ModGraph]:
    """(every import, runtime imports only) between robo_comp's modules."""
    mods = _modules()
    every: ModGraph = {m: set() for m in mods}
    runtime: ModGraph = {m: set() for m in mods}
    for m, p in mods.items():
        pkg = m if p.name == "__init__.py" else m.rpartition(".")[0]
        tree = ast.parse(p.read_text())
        types = _type_only(tree)
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = pkg.split(".")[: len(pkg.split(".")) - node.level + 1]
                    base = ".".join(up + ([base] if base else []))
                targets = [base] + [f"{base}.{a.name}" for a in node.names]
            else:
                continue
            for t in targets:
                while t and t not in mods:
                    t = t.rpartition(".")[0]
                if t and t != m and t != "robo_comp":
                    every[m].add(t)
                    if id(node) not in types:
                        runtime[m].add(t)
    return every, runtime


def package_of(module: str) -> str:
    """``robo_comp.core.server`` -> ``core``; a top-level module is its own package."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "robo_comp"


def packages(graph: ModGraph) -> PkgGraph:
    """The package graph of a module graph (an import inside one package is no edge)."""
    out: PkgGraph = {}
    for m, deps in graph.items():
        a = package_of(m)
        out.setdefault(a, set())
        for d in deps:
            b = package_of(d)
            if b != a:
                out[a].add(b)
    return out


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one node (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph.get(root, ()))))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph.get(w, ())))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    x = stack.pop()
                    on.discard(x)
                    comp.append(x)
                    if x == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def allowed_imports() -> dict[str, set[str] | None]:
    """The "may import" column of docs/architecture.md's table: package -> the packages it may
    import (None: anything, for the command-line entry points)."""
    rows: dict[str, set[str] | None] = {}
    for line in DOC.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 3 or not cells[0].startswith("`"):
            continue
        names = re.findall(r"`([a-z_]+)(?:/|\.py)?`", cells[0])
        may = cells[-1]
        allowed = None if may.strip() == "anything" else set(re.findall(r"`([a-z_]+)`", may))
        for name in names:
            rows[name] = allowed
    return rows


def layering_violations(pkgs: PkgGraph, allowed: dict[str, set[str] | None]) -> dict[str, list[str]]:
    """Per package, the packages it imports that its row does not allow (a package with no row
    is a violation too: every package is in the table)."""
    bad: dict[str, list[str]] = {}
    for a, deps in pkgs.items():
        if a == "robo_comp":
            continue
        if a not in allowed:
            bad[a] = ["(not in docs/architecture.md's table)"]
            continue
        may = allowed[a]
        if may is None:
            continue
        wrong = sorted(d for d in deps if d not in may and d != "robo_comp")
        if wrong:
            bad[a] = wrong
    return bad


def ui_to_ui(pkgs: PkgGraph) -> dict[str, list[str]]:
    """UIs that import another UI."""
    return {a: sorted(deps & UIS) for a, deps in pkgs.items() if a in UIS and deps & UIS}


def below_imports_ui(pkgs: PkgGraph, allowed: dict[str, set[str] | None]) -> dict[str, list[str]]:
    """Packages below the UIs (all but the UIs and the entry points) that import a UI."""
    return {a: sorted(deps & UIS) for a, deps in pkgs.items()
            if a not in UIS and allowed.get(a) is not None and deps & UIS}


def status_writers(root: Path = ROOT) -> list[str]:
    """Places outside the robot lifecycle that write a robot's ``status`` (``x.status = ...``)."""
    out = []
    for m, p in _modules(root).items():
        if m == "robo_comp.match.lifecycle":
            continue
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, (ast.Assign, ast.AugAssign, ast.AnnAssign)):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                for t in targets:
                    if isinstance(t, ast.Attribute) and t.attr == "status" and _is_robot_status(node.value):
                        out.append(f"{m}:{node.lineno}")
    return out


def _is_robot_status(value: ast.AST | None) -> bool:
    """An assigned value that names RobotStatus (``RobotStatus.LOST``, or a conditional of them)."""
    return value is not None and any(isinstance(n, ast.Name) and n.id == "RobotStatus" for n in ast.walk(value))


# ---------------------------------------------------------------------- the rules on the tree
@pytest.fixture(scope="module")
def graphs() -> tuple[ModGraph, ModGraph]:
    return _graphs()


def test_no_import_circle_of_modules(graphs):
    every, _ = graphs
    assert cycles(every) == []


def test_no_import_circle_of_packages(graphs):
    _, runtime = graphs
    assert cycles(packages(runtime)) == []


def test_every_package_imports_only_what_the_architecture_table_allows(graphs):
    _, runtime = graphs
    assert layering_violations(packages(runtime), allowed_imports()) == {}


def test_no_ui_imports_another_ui(graphs):
    _, runtime = graphs
    assert ui_to_ui(packages(runtime)) == {}


def test_nothing_below_the_uis_imports_one(graphs):
    _, runtime = graphs
    assert below_imports_ui(packages(runtime), allowed_imports()) == {}


def test_only_the_lifecycle_writes_a_robots_status():
    assert status_writers() == []


def test_the_table_names_every_package_and_only_real_ones(graphs):
    _, runtime = graphs
    table = set(allowed_imports())
    real = set(packages(runtime)) - {"robo_comp"}
    assert real - table == set(), "packages missing from docs/architecture.md's table"
    assert table - real == set(), "rows of docs/architecture.md's table name no package"
    for name, may in allowed_imports().items():
        assert may is None or may <= real | {"errors"}, f"{name}'s row names a package that does not exist"


# ---------------------------------------------------------------------- each rule can fail
def _planted(graph: ModGraph, src: str, dst: str) -> ModGraph:
    g = {m: set(d) for m, d in graph.items()}
    g.setdefault(src, set()).add(dst)
    return g


def test_the_cycle_finder_finds_a_circle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_a_planted_module_circle_fails(graphs):
    every, _ = graphs
    planted = _planted(every, "robo_comp.protocol.wire", "robo_comp.core.server")
    assert cycles(planted) != []


def test_a_planted_package_circle_fails(graphs):
    _, runtime = graphs
    # world imports protocol; a protocol module importing world closes a circle of packages
    # (without a circle of modules: the package rule sees what the module rule cannot)
    planted = _planted(runtime, "robo_comp.protocol.topics", "robo_comp.world.maps")
    assert ["protocol", "world"] in cycles(packages(planted))


@pytest.mark.parametrize("src, dst", [
    ("robo_comp.protocol.messages", "robo_comp.league.store"),  # the protocol stands alone
    ("robo_comp.match.model", "robo_comp.core.server"),  # the match has no sockets
    ("robo_comp.sandbox.child", "robo_comp.robots.host"),  # untrusted code's package holds no trusted part
    ("robo_comp.robots.host", "robo_comp.core.server"),  # clients reach a core only through the protocol
    ("robo_comp.engine.bench", "robo_comp.core.recovery"),  # the engine drives the match, not the core
])
def test_a_planted_layering_violation_fails(graphs, src, dst):
    _, runtime = graphs
    pkgs = packages(_planted(runtime, src, dst))
    assert package_of(dst) in layering_violations(pkgs, allowed_imports()).get(package_of(src), [])


def test_a_planted_ui_to_ui_import_fails(graphs):
    _, runtime = graphs
    assert ui_to_ui(packages(_planted(runtime, "robo_comp.web.server", "robo_comp.wall.render"))) == {"web": ["wall"]}


def test_a_planted_ui_import_below_fails(graphs):
    _, runtime = graphs
    pkgs = packages(_planted(runtime, "robo_comp.robots.host", "robo_comp.tui.app"))
    assert below_imports_ui(pkgs, allowed_imports()) == {"robots": ["tui"]}


def test_a_planted_package_missing_from_the_table_fails(graphs):
    _, runtime = graphs
    pkgs = packages(runtime)
    pkgs["newpkg"] = {"errors"}
    assert "newpkg" in layering_violations(pkgs, allowed_imports())


def test_a_planted_status_write_is_found(tmp_path):
    planted = tmp_path / "robo_comp" / "core"
    planted.mkdir(parents=True)
    (planted / "__init__.py").write_text("")
    (planted / "rogue.py").write_text("from robo_comp.protocol.states import RobotStatus\n"
                                      "def f(r):\n    r.status = RobotStatus.LOST\n")
    assert status_writers(tmp_path / "robo_comp") == ["robo_comp.core.rogue:3"]


def test_a_type_only_import_is_no_package_edge(tmp_path):
    tree = ast.parse("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import a\nimport b\n")
    types = _type_only(tree)
    kinds = {n.names[0].name: id(n) in types for n in ast.walk(tree) if isinstance(n, ast.Import)}
    assert kinds == {"a": True, "b": False}

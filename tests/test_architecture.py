"""The tree keeps its shape: no import circle in robo_comp/, and imports go one way
(see docs/architecture.md). Read from the source with ast: every import counts, also those
inside functions and under ``if TYPE_CHECKING:``."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent / "robo_comp"


def _modules() -> dict[str, Path]:
    mods = {}
    for p in ROOT.rglob("*.py"):
        if "template" in p.parts:  # team code, not robo_comp's
            continue
        parts = p.relative_to(ROOT.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        mods[name] = p
    return mods


def _graph() -> dict[str, set[str]]:
    mods = _modules()
    graph: dict[str, set[str]] = {m: set() for m in mods}
    for m, p in mods.items():
        pkg = m if p.name == "__init__.py" else m.rpartition(".")[0]
        for node in ast.walk(ast.parse(p.read_text())):
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
                if t and t != m:
                    graph[m].add(t)
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
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
                    work.append((w, iter(sorted(graph[w]))))
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


def test_the_cycle_finder_finds_a_circle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_circle_in_robo_comp():
    assert _cycles(_graph()) == []


def _imports_of(prefixes: tuple[str, ...]) -> dict[str, set[str]]:
    return {m: deps for m, deps in _graph().items() if m.startswith(prefixes)}


def test_clients_reach_the_core_only_through_the_protocol():
    """UIs, robot hosts, the public client and the team bench never import robo_comp.core."""
    outside = ("robo_comp.match", "robo_comp.tui", "robo_comp.wall", "robo_comp.web", "robo_comp.robots", "robo_comp.client",
               "robo_comp.ctl", "robo_comp.testing", "robo_comp.world", "robo_comp.sandbox",
               "robo_comp.protocol", "robo_comp.plugins", "robo_comp.scoring", "robo_comp.teams",
               "robo_comp.league")
    bad = {m: sorted(d for d in deps if d.startswith("robo_comp.core")) for m, deps in _imports_of(outside).items()}
    assert {m: d for m, d in bad.items() if d} == {}


def test_nothing_below_imports_a_ui():
    below = ("robo_comp.core", "robo_comp.match", "robo_comp.protocol", "robo_comp.robots", "robo_comp.world",
             "robo_comp.sandbox",
             "robo_comp.plugins", "robo_comp.scoring", "robo_comp.teams", "robo_comp.client", "robo_comp.league",
             "robo_comp.testing")
    ui = ("robo_comp.tui", "robo_comp.wall", "robo_comp.web")
    bad = {m: sorted(d for d in deps if d.startswith(ui)) for m, deps in _imports_of(below).items()}
    assert {m: d for m, d in bad.items() if d} == {}


def test_the_protocol_stands_alone():
    allowed = ("robo_comp.protocol", "robo_comp.errors", "robo_comp.teams.tokens", "robo_comp")
    bad = {m: sorted(d for d in deps if not d.startswith(allowed) or d == "robo_comp.teams")
           for m, deps in _imports_of(("robo_comp.protocol",)).items()}
    assert {m: d for m, d in bad.items() if d} == {}


def test_the_sandbox_holds_no_trusted_parts():
    """Untrusted code's package imports no core, robot host, hooks or UI."""
    banned = ("robo_comp.core", "robo_comp.robots", "robo_comp.plugins", "robo_comp.tui", "robo_comp.wall",
              "robo_comp.web", "robo_comp.client")
    bad = {m: sorted(d for d in deps if d.startswith(banned)) for m, deps in _imports_of(("robo_comp.sandbox",)).items()}
    assert {m: d for m, d in bad.items() if d} == {}


def test_the_match_model_imports_nothing_of_robo_comp():
    """``robo_comp.match`` is plain Python on plain data: it imports no other part of robo_comp
    (the core, the hosts and the bench all ask it; it asks none of them)."""
    bad = {m: sorted(d for d in deps if not d.startswith("robo_comp.match"))
           for m, deps in _imports_of(("robo_comp.match",)).items()}
    assert {m: d for m, d in bad.items() if d} == {}

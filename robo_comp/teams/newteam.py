"""``robo-comp new-team NAME [--dest DIR]``: start a team folder from the shipped template.

The template lives in ``robo_comp/teams/template/`` (package data, so it is there however
robo_comp was installed); the repository's ``team_templates/`` is a link to it, so that the
template is visible at the top level. The copy is a small team package:
``pyproject.toml``, ``README.md``, ``extensions/`` (uploads) and ``tests/`` (run with pytest,
using the fixtures of :mod:`robo_comp.testing`).
"""
from __future__ import annotations

import argparse
import re
import sys
from importlib import resources
from importlib.resources.abc import Traversable
from pathlib import Path

from robo_comp.errors import FieldError

NAME_RE = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,39}")
#: Names never copied out of the template (caches a test run may leave behind).
SKIP = {"__pycache__", ".pytest_cache"}
#: The project name in the template's pyproject.toml, replaced by the team's name.
PLACEHOLDER = 'name = "my-team"'


def template_root() -> Traversable:
    """The shipped team template (``robo_comp/teams/template``)."""
    return resources.files("robo_comp.teams").joinpath("template")


def template_files(root: Traversable | None = None, prefix: str = "") -> dict[str, bytes]:
    """Every file of the template as ``{relative posix path: bytes}`` (caches skipped)."""
    root = root if root is not None else template_root()
    out: dict[str, bytes] = {}
    for item in sorted(root.iterdir(), key=lambda t: t.name):
        if item.name in SKIP or item.name.endswith((".pyc", ".pyo")):
            continue
        rel = f"{prefix}{item.name}"
        if item.is_dir():
            out.update(template_files(item, rel + "/"))
        else:
            out[rel] = item.read_bytes()
    return out


def create_team(name: str, dest: str | Path = ".") -> Path:
    """Copy the template into ``dest/name`` and name the package after the team; return the folder.

    Raises :class:`~robo_comp.errors.FieldError` for a bad name or when the folder exists and
    is not empty.
    """
    if not NAME_RE.fullmatch(name):
        raise FieldError(f"team name {name!r}: use 1-40 letters, digits, '_' or '-', starting with a letter")
    target = Path(dest) / name
    if target.exists() and (not target.is_dir() or any(target.iterdir())):
        raise FieldError(f"{target} already exists and is not empty; choose another name or --dest")
    files = template_files()
    if not files:
        raise FieldError("the team template is missing from this robo_comp installation")
    for rel, data in files.items():
        path = target / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        if rel == "pyproject.toml":
            data = data.decode("utf-8").replace(PLACEHOLDER, f'name = "{name.lower()}"', 1).encode("utf-8")
        path.write_bytes(data)
    return target


def run(args: argparse.Namespace) -> int:
    """Run ``new-team``: copy the template and say what to do next."""
    target = create_team(args.name, args.dest)
    print(f"created team folder {target}\n"
          f"next: cd {target} && {Path(sys.executable).name} -m pytest   (then read README.md)")
    return 0


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add the ``new-team NAME [--dest DIR]`` subcommand to ``robo-comp``'s subparsers."""
    p = subparsers.add_parser(
        "new-team", help="start a team folder from the template (extensions, tests, README)",
        description="Copy the team template into DIR/NAME: pyproject.toml, README.md, extensions/ "
                    "(square, wander_code, explorer) and tests/ that run with pytest.")
    p.add_argument("name", metavar="NAME", help="the team folder and package name, e.g. red_rovers")
    p.add_argument("--dest", default=".", metavar="DIR", help="where to create NAME/ (default: here)")
    p.set_defaults(func=run)
    return p


def main(argv: list[str] | None = None) -> int:
    """Run ``new-team`` on its own (``python -m robo_comp.teams.newteam NAME``)."""
    parser = argparse.ArgumentParser(prog="robo-comp")
    sub = parser.add_subparsers(dest="command", required=True)
    add_parser(sub)
    args = parser.parse_args(["new-team", *(sys.argv[1:] if argv is None else argv)])
    try:
        return run(args)
    except FieldError as e:
        print(f"robo-comp new-team: {e.message}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

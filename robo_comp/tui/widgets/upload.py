"""Pieces of the upload dialog: a file picker that shows Python files, and the checked result."""
from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

from rich.text import Text
from textual.widgets import DirectoryTree, Static

#: Largest file the console sends (the core has its own, stricter limits).


class PythonTree(DirectoryTree):
    """A directory tree that lists folders and ``.py`` files only (hidden ones left out)."""

    def filter_paths(self, paths: Iterable[Path]) -> Iterable[Path]:
        return [p for p in paths if not p.name.startswith(".") and not p.name == "__pycache__"
                and (p.is_dir() or p.suffix == ".py")]


class UploadResult(Static):
    """The core's verdict per robot: ✓ name version and tasks, or ✗ the checker's message."""

    DEFAULT_CSS = """
    UploadResult { height: auto; max-height: 8; }
    """

    def show_results(self, reply: dict[str, Any]) -> bool:
        """Draw an ``upload`` reply; True when every robot accepted it."""
        results = reply.get("results") or []
        t = Text()
        if not results and reply.get("upload_id") is not None:
            t.append(f"⧗ upload {reply['upload_id']} waits for the referee's approval", style="yellow")
            self.update(t)
            return True
        all_ok = bool(results)
        for i, r in enumerate(results):
            if i:
                t.append("\n")
            if r.get("ok"):
                t.append("✓ ", style="bold green")
                t.append(f"robot {r.get('tag')}: {r.get('name', '')} {r.get('version', '')}".rstrip())
                tasks = r.get("tasks") or []
                if tasks:
                    names = [x.get("name", x) if isinstance(x, dict) else str(x) for x in tasks]
                    t.append(f" · tasks {', '.join(names)}", style="dim")
                if r.get("message"):
                    t.append(f" · {r['message']}", style="dim")
            else:
                all_ok = False
                t.append("✗ ", style="bold red")
                t.append(f"robot {r.get('tag')}: {r.get('message', 'refused')}", style="red")
        if not results:
            t.append("the core sent no results", style="yellow")
        self.update(t)
        return all_ok

    def show_error(self, message: str) -> None:
        """Draw a refusal of the whole upload."""
        self.update(Text.assemble(("✗ ", "bold red"), (message, "red")))

    def show_busy(self, filename: str) -> None:
        """Say the upload is being checked."""
        self.update(Text(f"⧗ sending {filename}; the robots check it…", style="yellow"))

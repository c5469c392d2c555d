"""Commands the documentation gives, run as written: a newcomer who follows the organiser's
guide word for word meets no traceback and no step that fails."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def blocks(doc: Path, section: str, lang: str) -> list[str]:
    """The ```lang code blocks of the section whose heading starts with ``section``."""
    text = doc.read_text()
    start = text.index(f"\n## {section}")
    end = text.find("\n## ", start + 4)
    part = text[start:end if end > 0 else None]
    return re.findall(rf"```{lang}\n(.*?)```", part, re.S)


def test_organiser_section_1_as_written(tmp_path: Path) -> None:
    doc = ROOT / "docs" / "organiser.md"
    sh = blocks(doc, "1.", "sh")
    assert len(sh) == 2, sh
    (tmp_path / "team_templates").symlink_to(ROOT / "team_templates")  # the guide runs in the repository
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}")
    for block in sh:
        p = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", block], cwd=tmp_path, env=env, capture_output=True,
                           text=True, timeout=120)
        assert p.returncode == 0 and "Traceback" not in p.stderr, f"{block}\n{p.stdout}\n{p.stderr}"
    assert (tmp_path / "arenas" / "final.toml").is_file()
    assert "playable" in p.stdout or "cost" in p.stdout  # the second block checked and planned
    (py,) = blocks(doc, "1.", "python")
    p = subprocess.run([sys.executable, "-c", py], cwd=tmp_path, env=env, capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 0, f"{py}\n{p.stdout}\n{p.stderr[-3000:]}"
    assert (tmp_path / "final-dryrun.jsonl").is_file()

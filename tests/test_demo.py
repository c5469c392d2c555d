"""``robo-comp demo`` as a newcomer runs it: a real match that rescues victims, ends with a
winner, and leaves its state folder for ``robo-comp web --replay``, saying so."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

from robo_comp.web.replay import Recording


def test_demo_finds_victims_and_leaves_a_replay(tmp_path: Path) -> None:
    env = dict(os.environ, TMPDIR=str(tmp_path))  # the demo's kept state folder goes in the test's folder
    p = subprocess.run([sys.executable, "-m", "robo_comp.cli", "demo", "--duration", "30"], capture_output=True,
                       text=True, timeout=300, env=env)
    out = p.stdout + p.stderr
    assert p.returncode == 0, out[-3000:]
    assert len(re.findall(r"reported \w+ at \(\d+, \d+\) with \d+ pictures: confirmed", out)) >= 2, out[-3000:]
    scores = dict(re.findall(r"^\s+\d\. (\w+)\s+(-?[\d.]+) points", out, re.M))
    assert len(scores) == 2 and all(float(v) > 0 for v in scores.values()), out[-1500:]
    m = re.search(r"watch it again with: robo-comp web --replay (\S+)", out)
    assert m, out[-1500:]
    log = Path(m.group(1))
    assert log.is_file() and log.parent.parent == tmp_path
    assert (log.parent / "results.json").is_file()
    # the replay tells the story: the finds, and the victims revealed at the end
    view = Recording(log).build("public")
    assert '"kind":"find"' in view.story_json and '"found_by":["' in view.story_json

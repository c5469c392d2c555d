"""Our uploads, checked the way the robots check them: through the real sandbox.

``robo_bench`` (from robo_comp's pytest plugin) runs the modules in the same restricted child
process as a robot host would, and answers the robot API from a seeded simulation of the
scenario in pyproject.toml, so these tests are fast and give the same result every time.
"""
from pathlib import Path

import pytest

from robo_comp.errors import UploadError
from robo_comp.testing import Bench, TaskError

EXTENSIONS = Path(__file__).parent.parent / "extensions"


@pytest.mark.parametrize("path", sorted(EXTENSIONS.glob("*.py")), ids=lambda p: p.name)
def test_every_upload_passes_the_contract(robo_bench, path):
    info = robo_bench.load(path)
    assert info.tasks, f"{path.name} declares no tasks"
    assert set(info.tasks) <= set(robo_bench.tasks())


BROKEN = '''MANIFEST = {"name": "bad", "version": "1", "kind": "extension", "tasks": {"t": {"args": []}}}

def t(robot):
    return 1

open("/etc/passwd")
'''


def test_a_broken_upload_is_refused_with_file_and_line(robo_bench):
    with pytest.raises(UploadError) as err:
        robo_bench.load("bad.py", BROKEN)  # there is no open() in the sandbox: line 6 fails
    assert err.value.details == {"file": "bad.py", "line": 6, "rule": "module"}
    assert "open" in err.value.message


@pytest.fixture
def demo():
    """The practice room (bundled demo_room): victim v1, an adult, sits at (9, 5) in the closet."""
    with Bench("demo_room", "red", seed=0) as bench:
        bench.load(EXTENSIONS / "explorer.py")
        yield bench


def test_explore_then_report_scores_a_victim(demo):
    out = demo.run("explore", [[9, 6]])
    assert out["visited"] == [[9, 6]] and len(out["pictures"]) == 4
    assert demo.true_cell() == (9, 6)
    answer = demo.run("report_victim", 9, 5, "adult")
    assert answer["state"] == "confirmed", answer
    assert demo.score() == 15  # 10 for an adult + 5 for finding it first


def test_unreachable_points_are_skipped(demo):
    out = demo.run("explore", [[0, 0], [3, 3]])  # (0, 0) is the outer wall: plan() refuses it
    assert out["skipped"] == [[0, 0]] and out["visited"] == [[3, 3]]
    assert "cannot be reached" in demo.log_text()


def test_a_report_needs_pictures_first(demo):
    with pytest.raises(TaskError, match="no pictures yet"):
        demo.run("report_victim", 9, 5, "adult")


def test_a_wrong_report_costs_points(demo):
    demo.run("explore", [[3, 3]])
    answer = demo.run("report_victim", 3, 3, "adult")
    assert answer["state"] == "rejected"
    assert demo.score() == -5

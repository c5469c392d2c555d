"""Files at rest: the league folder, its database, match logs and reports, the core's state folder
and pictures are the organiser's (0700 folders, 0600 files) whatever the umask; a submission
handed in as a folder cannot pull in files that are not the team's own (docs/security.md,
"Team data at rest")."""
from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path

import pytest

from conftest import CoreHandle, wait_robots
from robo_comp.errors import FieldError, RoboCompError, UploadError
from robo_comp.league import reference, season
from robo_comp.league.report import write_report
from robo_comp.league.runner import LocalRunner
from robo_comp.league.store import LeagueStore


def mode(p: Path) -> int:
    return stat.S_IMODE(p.stat().st_mode)


@pytest.fixture
def open_umask() -> Iterator[None]:
    """The usual umask (022): new files readable by every user unless made private."""
    old = os.umask(0o022)
    try:
        yield
    finally:
        os.umask(old)


def test_the_league_folder_its_database_logs_and_report_are_private(tmp_path: Path, open_umask: None) -> None:
    root = tmp_path / "lg"
    with LeagueStore(root, create=True) as store:
        store.configure(scenarios=["demo_room"], robots=2, seconds=30)
        season.submit_reference(store, 2)
        assert mode(root) == 0o700
        for name in ("league.db", "league.db-wal", "league.db-shm"):  # every team's source is in there
            assert (root / name).exists() and mode(root / name) == 0o600, name
        fig = season.run_format(store, LocalRunner(1), "round-robin")
        assert fig["matches"] == 1 and not fig["failed"]
        logs = [store.log_path(m.id) for m in store.matches()]
        assert logs and all(mode(p) == 0o600 for p in logs)
        report = write_report(tmp_path / "out" / "report.html", season.league_view(store))
        assert mode(report) == 0o600
    os.chmod(root, 0o755)  # a league made before: opening it makes it private again
    os.chmod(root / "league.db", 0o644)
    with LeagueStore(root):
        assert mode(root) == 0o700 and mode(root / "league.db") == 0o600


def test_pictures_and_the_state_folder_are_private(core: CoreHandle) -> None:
    """A robot's pictures (``STATE/pictures``) are 0600 in 0700, the state folder 0700."""
    core.robots("red", 1)
    red = core.client("red")
    row = wait_robots(red, 1)[0]
    from conftest import next_event_where

    red.watch(True)
    tid = red.give(row["tag"], "examineArea", [int(row["x"]), int(row["y"])])["task_id"]
    done = next_event_where(red, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == tid, 30)
    assert done["data"]["ok"] and done["data"]["result"]["pictures"]
    pics = core.state / "pictures"
    files = list(pics.iterdir())
    assert files and all(mode(f) == 0o600 for f in files)
    assert mode(pics) == 0o700 and mode(core.state) == 0o700


# ---------------------------------------------------------------------- submissions
ORGANISER_SECRET = "ORGANISER-ONLY = this line must never be quoted\n"


@pytest.fixture
def organiser_file(tmp_path: Path) -> Path:
    """A file of the organiser's (not valid Python: an error about it would quote its line)."""
    p = tmp_path / "organiser" / "secret.py"
    p.parent.mkdir()
    p.write_text(ORGANISER_SECRET)
    return p


def team_folder(tmp_path: Path) -> Path:
    folder = tmp_path / "handed-in" / "extensions"
    folder.mkdir(parents=True)
    (folder / "play.py").write_text(reference.source("sitter"))
    return folder.parent


def refused(path: Path) -> RoboCompError:
    with pytest.raises((UploadError, FieldError)) as e:
        season.read_submission(path)
    assert "ORGANISER-ONLY" not in e.value.message and "organiser" not in e.value.message
    return e.value


def test_a_symlink_in_a_submission_is_refused(tmp_path: Path, organiser_file: Path) -> None:
    """A link to the organiser's file (or to another team's source) is refused before it is read,
    naming the link in the team's folder only."""
    team = team_folder(tmp_path)
    (team / "extensions" / "helper.py").symlink_to(organiser_file)
    e = refused(team)
    assert "helper.py" in e.message and "symbolic link" in e.message


def test_a_linked_folder_a_linked_file_and_a_hard_link_are_refused(tmp_path: Path, organiser_file: Path) -> None:
    team = tmp_path / "t1"
    team.mkdir()
    (team / "extensions").symlink_to(organiser_file.parent)
    assert "symbolic link" in refused(team).message
    link = tmp_path / "entry.py"
    link.symlink_to(organiser_file)
    assert "symbolic link" in refused(link).message
    team2 = team_folder(tmp_path / "t2")
    os.link(organiser_file, team2 / "extensions" / "helper.py")
    assert "hard link" in refused(team2).message


def test_a_plain_team_folder_still_submits(tmp_path: Path) -> None:
    files = season.read_submission(team_folder(tmp_path))
    assert list(files) == ["play.py"]

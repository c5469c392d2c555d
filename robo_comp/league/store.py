"""A league's state in one SQLite file: submissions, matches, results and ratings.

``LEAGUE/league.db`` holds everything but the match logs, which go to
``LEAGUE/matches/<id>/events.log``. SQLite is the embedded default: one file, nothing to start,
safe against a crash mid-write (each change is one ``BEGIN IMMEDIATE`` transaction, so two
``league`` commands on one folder take turns).

A match's status: ``scheduled`` → ``running`` → ``done`` or ``failed`` (played again by the
next ``league run``); ``cancelled`` by the organiser (never played or rated).
"""
from __future__ import annotations

import hashlib
import json
import os
import sqlite3
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robo_comp.errors import FieldError
from robo_comp.private_files import private_dir, private_file
from robo_comp.league.ratings import initial

SCHEMA = """
CREATE TABLE IF NOT EXISTS settings (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS submissions (
    id INTEGER PRIMARY KEY, team TEXT NOT NULL, version TEXT NOT NULL, who TEXT NOT NULL,
    at REAL NOT NULL, files TEXT NOT NULL, last REAL, UNIQUE (team, version));
CREATE TABLE IF NOT EXISTS matches (
    id INTEGER PRIMARY KEY, format TEXT NOT NULL, round INTEGER NOT NULL, scenario TEXT NOT NULL,
    seed INTEGER NOT NULL, ranked INTEGER NOT NULL, status TEXT NOT NULL, entrants TEXT NOT NULL,
    result TEXT, error TEXT, attempts INTEGER NOT NULL DEFAULT 0, scheduled REAL NOT NULL,
    finished REAL, rated INTEGER NOT NULL DEFAULT 0);
CREATE TABLE IF NOT EXISTS ratings (
    team TEXT PRIMARY KEY, mu REAL NOT NULL, sigma REAL NOT NULL, matches INTEGER NOT NULL,
    wins INTEGER NOT NULL);
CREATE TABLE IF NOT EXISTS rating_history (
    match_id INTEGER NOT NULL, team TEXT NOT NULL, mu REAL NOT NULL, sigma REAL NOT NULL,
    PRIMARY KEY (match_id, team));
"""

#: Settings a new league gets (``robo-comp league init`` changes them through :meth:`LeagueStore.configure`).
DEFAULTS: dict[str, Any] = {"name": "League", "scenarios": ["office", "generated:1:0.5"], "robots": 4,
                            "seconds": 300, "teams_per_match": 2, "seed": 0, "debug_replay": "team"}


@dataclass(frozen=True)
class Submission:
    """One version of a team's code: ``files`` maps a module's file name to its source."""

    id: int
    team: str
    version: str
    who: str
    at: float
    files: dict[str, str]


@dataclass(frozen=True)
class MatchRow:
    """A scheduled or played match. ``entrants`` are ``(team, submission id)`` pairs; ``result``
    is what :func:`robo_comp.league.engine.play_match` returned (None until played)."""

    id: int
    format: str
    round: int
    scenario: str
    seed: int
    ranked: bool
    status: str
    entrants: list[tuple[str, int]]
    result: dict[str, Any] | None
    error: str | None
    attempts: int

    @property
    def teams(self) -> list[str]:
        """The teams of the match, in slot order."""
        return [t for t, _ in self.entrants]


def version_of(files: dict[str, str]) -> str:
    """A submission's version: the first 12 hex digits of the SHA-256 of its files."""
    h = hashlib.sha256()
    for name in sorted(files):
        h.update(name.encode() + b"\0" + files[name].encode() + b"\0")
    return h.hexdigest()[:12]


class LeagueStore:
    """The league folder ``root``: its SQLite database and its match logs."""

    def __init__(self, root: str | Path, *, create: bool = False) -> None:
        self.root = Path(root)
        db = self.root / "league.db"
        if self.root.exists() and not self.root.is_dir():
            raise FieldError(f"{self.root} is a file, not a league folder")
        if not db.exists() and not create:
            raise FieldError(f"{self.root} is not a league (no league.db); start one with "
                             f"'robo-comp league init {self.root}'")
        private_dir(self.root)  # every team's source and logs: the organiser's alone (0700)
        if not db.exists():
            os.close(os.open(db, os.O_WRONLY | os.O_CREAT, 0o600))  # SQLite's WAL and SHM take its mode
        for f in (db, db.with_name("league.db-wal"), db.with_name("league.db-shm")):
            private_file(f)
        try:
            self.db = sqlite3.connect(db, isolation_level=None, timeout=30.0)
            self.db.execute("PRAGMA journal_mode=WAL")
            self.db.executescript(SCHEMA)
            columns = {r[1] for r in self.db.execute("PRAGMA table_info(submissions)")}
            if "last" not in columns:  # a league made before submissions kept their last time
                self.db.execute("ALTER TABLE submissions ADD COLUMN last REAL")
        except sqlite3.DatabaseError as e:
            raise db_error(self.root, e, f"it cannot be read as a league database (SQLite says {e})") from None
        if create:
            with self.transaction():
                for k, v in DEFAULTS.items():
                    self.db.execute("INSERT OR IGNORE INTO settings VALUES (?, ?)", (k, json.dumps(v)))

    def _json(self, text: Any, what: str) -> Any:
        """A JSON column's value; :class:`LeagueDamaged` when the bytes stored are not JSON."""
        try:
            return json.loads(text)
        except (TypeError, ValueError) as e:
            raise LeagueDamaged(self.root, f"{what} cannot be read ({e})") from None

    @contextmanager
    def transaction(self) -> Iterator[sqlite3.Connection]:
        """One write transaction (``BEGIN IMMEDIATE``: another writer waits): committed when
        the block ends, rolled back when it raises."""
        self.db.execute("BEGIN IMMEDIATE")
        try:
            yield self.db
        except BaseException:
            self.db.execute("ROLLBACK")
            raise
        self.db.execute("COMMIT")

    def close(self) -> None:
        """Close the database (and give up the run lock, if this store holds it)."""
        self.unlock()
        self.db.close()

    # ------------------------------------------------------------------ one run at a time
    def lock(self) -> None:
        """Take the league's run lock (``LEAGUE/run.lock``): one ``league run`` per league at a
        time. The lock is an ``flock`` the kernel drops when the process ends however it ends,
        so a killed run never leaves it behind. Raises :class:`FieldError` naming the run that
        holds it."""
        import fcntl

        if getattr(self, "_lock", None) is not None:
            return
        path = self.root / "run.lock"
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 200, 0).decode("utf-8", "replace").strip() or "another process"
            os.close(fd)
            raise FieldError(f"another 'league run' is playing {self.root} ({holder}); one run per league at a "
                             "time: wait for it to end, or stop it (Ctrl-C) and run again") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()}, since {time.strftime('%H:%M:%S')}".encode(), 0)
        self._lock: int | None = fd

    def unlock(self) -> None:
        """Give up the run lock (nothing if not held)."""
        fd = getattr(self, "_lock", None)
        if fd is not None:
            self._lock = None
            os.close(fd)  # closing the descriptor drops the flock

    def __enter__(self) -> LeagueStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ settings
    def settings(self) -> dict[str, Any]:
        """The league's settings (name, scenario pool, robots, seconds, teams per match, seed)."""
        out = dict(DEFAULTS)
        out.update({k: self._json(v, f"setting {k!r}") for k, v in self.db.execute("SELECT key, value FROM settings")})
        return out

    def configure(self, **values: Any) -> None:
        """Change settings."""
        with self.transaction():
            for k, v in values.items():
                self.db.execute("INSERT OR REPLACE INTO settings VALUES (?, ?)", (k, json.dumps(v)))

    # ------------------------------------------------------------------ submissions
    def add_submission(self, team: str, files: dict[str, str], who: str) -> tuple[Submission, bool]:
        """Store a version of ``team``'s code; returns it and whether it is new. The same files
        again are the same version, which becomes the team's newest again (a team can go back
        to an earlier version by submitting it again)."""
        version = version_of(files)
        now = time.time()
        with self.transaction():
            row = self.db.execute("SELECT id FROM submissions WHERE team = ? AND version = ?",
                                  (team, version)).fetchone()
            if row is not None:
                self.db.execute("UPDATE submissions SET last = ? WHERE id = ?", (now, row[0]))
                sid, new = int(row[0]), False
            else:
                cur = self.db.execute(
                    "INSERT INTO submissions (team, version, who, at, files, last) VALUES (?, ?, ?, ?, ?, ?)",
                    (team, version, who, now, json.dumps(files, sort_keys=True), now))
                sid, new = int(cur.lastrowid or 0), True
            self.db.execute("INSERT OR IGNORE INTO ratings VALUES (?, ?, ?, 0, 0)", (team, *initial()))
        return self.submission(sid), new

    def submission(self, sid: int) -> Submission:
        """Submission ``sid``."""
        row = self.db.execute("SELECT id, team, version, who, at, files FROM submissions WHERE id = ?",
                              (sid,)).fetchone()
        if row is None:
            raise FieldError(f"there is no submission {sid}")
        return Submission(row[0], row[1], row[2], row[3], row[4], self._json(row[5], f"submission {row[0]}'s files"))

    def submissions(self, team: str | None = None) -> list[Submission]:
        """Every submission (of ``team``), oldest first."""
        q = "SELECT id FROM submissions" + (" WHERE team = ?" if team else "") + " ORDER BY id"
        return [self.submission(r[0]) for r in self.db.execute(q, (team,) if team else ())]

    def newest(self) -> dict[str, Submission]:
        """Each team's newest submission (the one submitted last), by team name."""
        out: dict[str, Submission] = {}
        for (sid,) in self.db.execute("SELECT id FROM submissions ORDER BY COALESCE(last, at), id"):
            s = self.submission(sid)
            out[s.team] = s
        return dict(sorted(out.items()))

    # ------------------------------------------------------------------ matches
    def schedule(self, fmt: str, rnd: int, groups: Iterable[list[str]], *, ranked: bool = True,
                 per_round: bool = False) -> list[int]:
        """Schedule one match per group of team names (each team's newest version) in round
        ``rnd``; see :meth:`schedule_rounds`."""
        return self.schedule_rounds(fmt, [(rnd, list(groups))], ranked=ranked, per_round=per_round)

    def schedule_rounds(self, fmt: str, rounds: Iterable[tuple[int, list[list[str]]]], *,
                        ranked: bool = True, per_round: bool = False) -> list[int]:
        """Schedule rounds of matches, ``[(round, [group of team names, ...]), ...]``: each
        match gets a scenario of the pool and an order of its teams (their start sides) so that
        every team plays every scenario and side as evenly as the numbers allow, counting the
        league's earlier matches (:func:`robo_comp.league.schedule.balance`), and a seed from
        the league's seed and the match id. ``per_round``: every match of round ``r`` on the
        pool's scenario ``(r − 1) mod len(pool)`` (Swiss rounds, scheduled one at a time).
        One transaction: a bad group schedules nothing."""
        from robo_comp.league.schedule import balance

        cfg = self.settings()
        newest = self.newest()
        pool = list(cfg["scenarios"])
        rounds = [(int(r), [list(g) for g in groups]) for r, groups in rounds]
        prior: dict[str, list[int]] = {}
        sides: dict[str, list[int]] = {}
        use = [0] * len(pool)

        def tally(teams: list[str], k: int) -> None:
            """Count a match of ``teams`` (in side order) on scenario ``k``."""
            use[k] += 1
            for i, team in enumerate(teams):
                prior.setdefault(team, [0] * len(pool))[k] += 1
                row = sides.setdefault(team, [0] * max(2, len(teams)))
                row.extend([0] * (i + 1 - len(row)))
                row[i] += 1

        for m in self.matches():
            if m.status != "cancelled" and m.scenario in pool:
                tally(m.teams, pool.index(m.scenario))
        flat = [g for _, groups in rounds for g in groups]
        for teams in flat:
            missing = [t for t in teams if t not in newest]
            if missing:
                raise FieldError(f"team(s) {', '.join(missing)} have no submission")
            if len(set(teams)) != len(teams):
                raise FieldError(f"a match cannot have a team twice ({', '.join(teams)})")
        if per_round:
            placed_list: list[tuple[list[str], int]] = []
            for rnd, groups in rounds:
                got = balance(groups, len(pool), prior=prior, prior_sides=sides, prior_use=use,
                              scenario=(rnd - 1) % len(pool))
                for g, k in got:
                    tally(g, k)
                placed_list += got
            placed = iter(placed_list)
        else:
            placed = iter(balance(flat, len(pool), prior=prior, prior_sides=sides, prior_use=use))
        ids = []
        with self.transaction():
            for rnd, groups in rounds:
                for _ in groups:
                    ids.append(self._insert(fmt, rnd, *next(placed), pool, newest, cfg, ranked))
        return ids

    def _insert(self, fmt: str, rnd: int, teams: list[str], scenario: int, pool: list[str],
                newest: dict[str, Submission], cfg: dict[str, Any], ranked: bool) -> int:
        """One scheduled match (inside a transaction); returns its id."""
        entrants = [[t, newest[t].id] for t in teams]
        cur = self.db.execute(
            "INSERT INTO matches (format, round, scenario, seed, ranked, status, entrants, scheduled) "
            "VALUES (?, ?, ?, ?, ?, 'scheduled', ?, ?)",
            (fmt, rnd, pool[scenario], 0, int(ranked), json.dumps(entrants), time.time()))
        mid = int(cur.lastrowid or 0)
        self.db.execute("UPDATE matches SET seed = ? WHERE id = ?", (match_seed(int(cfg["seed"]), mid), mid))
        return mid

    def match(self, mid: int) -> MatchRow:
        """Match ``mid``."""
        row = self.db.execute("SELECT id, format, round, scenario, seed, ranked, status, entrants, result, error, "
                              "attempts FROM matches WHERE id = ?", (mid,)).fetchone()
        if row is None:
            raise FieldError(f"there is no match {mid}")
        return MatchRow(row[0], row[1], row[2], row[3], row[4], bool(row[5]), row[6],
                        [(t, s) for t, s in self._json(row[7], f"match {mid}'s entrants")],
                        self._json(row[8], f"match {mid}'s result") if row[8] else None,
                        row[9], row[10])

    def matches(self, status: str | None = None, fmt: str | None = None) -> list[MatchRow]:
        """Matches (with ``status``, of format ``fmt``), by id."""
        where, args = [], []
        if status:
            where.append("status = ?")
            args.append(status)
        if fmt:
            where.append("format = ?")
            args.append(fmt)
        q = "SELECT id FROM matches" + (" WHERE " + " AND ".join(where) if where else "") + " ORDER BY id"
        return [self.match(r[0]) for r in self.db.execute(q, args)]

    def log_path(self, mid: int) -> Path:
        """Where match ``mid``'s event log goes."""
        return self.root / "matches" / str(mid) / "events.log"

    def spec(self, mid: int) -> dict[str, Any]:
        """What :func:`robo_comp.league.engine.play_match` needs to play match ``mid``."""
        m = self.match(mid)
        cfg = self.settings()
        entrants = []
        for team, sid in m.entrants:
            s = self.submission(sid)
            entrants.append({"team": team, "version": s.version, "files": s.files})
        return {"id": m.id, "scenario": m.scenario, "seed": m.seed, "seconds": cfg["seconds"],
                "robots": cfg["robots"], "entrants": entrants, "log": str(self.log_path(m.id)),
                "debug_replay": cfg.get("debug_replay", "team"), "rules": cfg.get("rules")}

    def started(self, mid: int) -> None:
        """Match ``mid`` is being played (one more attempt)."""
        self.db.execute("UPDATE matches SET status = 'running', attempts = attempts + 1 WHERE id = ?", (mid,))

    def interrupted(self, mids: Iterable[int]) -> int:
        """Matches of ``mids`` still ``running`` when their run stopped become ``failed`` (to be
        played again); returns how many."""
        n = 0
        with self.transaction():
            for mid in mids:
                n += self.db.execute("UPDATE matches SET status = 'failed', error = ? WHERE id = ? AND "
                                     "status = 'running'", ("the run stopped before this match ended", mid)).rowcount
        return n

    def cancel(self, mid: int, why: str) -> None:
        """The organiser takes match ``mid`` out of the league: never played or rated (a match
        that cannot be played would otherwise hold up the ratings of every later match)."""
        m = self.match(mid)
        if m.status == "done":
            raise FieldError(f"match {mid} has been played; a played match stays in the league")
        self.db.execute("UPDATE matches SET status = 'cancelled', error = ? WHERE id = ?", (why[:2000], mid))

    def unrated(self) -> list[int]:
        """The ranked matches not rated yet (cancelled ones aside), by id."""
        return [r[0] for r in self.db.execute(
            "SELECT id FROM matches WHERE ranked = 1 AND rated = 0 AND status != 'cancelled' ORDER BY id")]

    def finished(self, mid: int, result: dict[str, Any]) -> None:
        """Store match ``mid``'s result."""
        self.db.execute("UPDATE matches SET status = 'done', result = ?, error = NULL, finished = ? WHERE id = ?",
                        (json.dumps(result, sort_keys=True), time.time(), mid))

    def failed(self, mid: int, error: str) -> None:
        """Match ``mid`` could not be played (``error`` says why); it stays to be played again."""
        self.db.execute("UPDATE matches SET status = 'failed', error = ? WHERE id = ?", (error[:2000], mid))

    # ------------------------------------------------------------------ ratings
    def ratings(self) -> dict[str, tuple[float, float, int, int]]:
        """Team → (μ, σ, matches rated, wins)."""
        return {r[0]: (r[1], r[2], r[3], r[4]) for r in self.db.execute("SELECT team, mu, sigma, matches, wins FROM ratings")}

    def store_rating(self, mid: int, new: dict[str, tuple[float, float]], winners: set[str]) -> bool:
        """Record the ratings after match ``mid`` (one transaction; nothing when it is rated
        already, so two runs on one league cannot rate a match twice). Returns whether it stored them."""
        with self.transaction():
            if self.db.execute("SELECT rated FROM matches WHERE id = ?", (mid,)).fetchone()[0]:
                return False
            for team, (mu, sigma) in new.items():
                self.db.execute("UPDATE ratings SET mu = ?, sigma = ?, matches = matches + 1, wins = wins + ? "
                                "WHERE team = ?", (mu, sigma, int(team in winners), team))
                self.db.execute("INSERT OR REPLACE INTO rating_history VALUES (?, ?, ?, ?)", (mid, team, mu, sigma))
            self.db.execute("UPDATE matches SET rated = 1 WHERE id = ?", (mid,))
        return True

    def history(self) -> dict[str, list[tuple[int, float, float]]]:
        """Team → [(match id, μ, σ), ...] in match order."""
        out: dict[str, list[tuple[int, float, float]]] = {}
        for mid, team, mu, sigma in self.db.execute(
                "SELECT match_id, team, mu, sigma FROM rating_history ORDER BY match_id"):
            out.setdefault(team, []).append((mid, mu, sigma))
        return out


class LeagueDamaged(FieldError):
    """``league.db`` holds bytes that are not what the league wrote (a damaged disk, an edit)."""

    def __init__(self, root: Path, what: str) -> None:
        super().__init__(f"{root / 'league.db'} is damaged: {what}. 'robo-comp league repair {root}' keeps "
                         "everything that can still be read (a copy of the damaged file stays beside it) and "
                         "puts damaged matches back to be played again")


#: SQLite errors that say nothing about the file's bytes (another program holds it, it cannot be
#: opened or written, the disk is full): ``league repair`` would not help with them.
NOT_DAMAGE = ("SQLITE_BUSY", "SQLITE_LOCKED", "SQLITE_CANTOPEN", "SQLITE_READONLY", "SQLITE_PERM", "SQLITE_FULL")


def db_error(root: Path, e: sqlite3.Error, damaged: str) -> FieldError:
    """The error to show for SQLite's ``e`` on the league at ``root``: :class:`LeagueDamaged`
    (``damaged`` says what) when the file's bytes may be at fault; else a sentence that the
    league is fine and what to wait for, since a repair would not help."""
    if str(getattr(e, "sqlite_errorname", "")).startswith(NOT_DAMAGE):
        return FieldError(f"{root / 'league.db'} cannot be used right now (SQLite says {e}): another program "
                          "holds it, or the file or its disk cannot be written. The league is not damaged: try "
                          "again when that is over")
    return LeagueDamaged(root, damaged)


def repair(root: str | Path) -> list[str]:
    """Recover the league at ``root`` from a damaged ``league.db``; returns what was done, one
    sentence each.

    The damaged file is kept as ``league.db.damaged-TIME``. Rows are copied table by table
    into a fresh database, row by row where a table cannot be read whole (rows on damaged
    pages are lost and said so). Then every JSON value is checked: a match whose result is
    damaged goes back to ``failed`` and is played again by the next ``league run`` (a match is
    deterministic: it gives the same result); a match whose entrants are damaged is cancelled;
    a damaged setting goes back to its default; a damaged submission is dropped."""
    import shutil

    root = Path(root)
    db = root / "league.db"
    if not db.is_file():
        raise FieldError(f"{root} is not a league (no league.db)")
    done: list[str] = []
    kept = root / f"league.db.damaged-{time.strftime('%Y%m%d-%H%M%S')}"
    for suffix in ("", "-wal", "-shm"):
        if (root / f"league.db{suffix}").exists():
            shutil.copyfile(root / f"league.db{suffix}", Path(f"{kept}{suffix}"))
    done.append(f"the damaged file is kept as {kept.name}")
    fresh = root / "league.db.repairing"
    fresh.unlink(missing_ok=True)
    new = sqlite3.connect(fresh, isolation_level=None)
    new.executescript(SCHEMA)
    try:
        old = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    except sqlite3.DatabaseError as e:
        raise FieldError(f"{db} cannot be opened at all ({e}); restore it from a backup") from None
    tables = ("settings", "submissions", "matches", "ratings", "rating_history")
    for table in tables:
        try:
            rows = old.execute(f"SELECT * FROM {table}").fetchall()
        except sqlite3.DatabaseError:
            rows = []
            try:
                ids = [r[0] for r in old.execute(f"SELECT rowid FROM {table}")]
            except sqlite3.DatabaseError:
                ids = []
            for rid in ids:
                try:
                    rows.extend(old.execute(f"SELECT * FROM {table} WHERE rowid = ?", (rid,)).fetchall())
                except sqlite3.DatabaseError:
                    done.append(f"{table}: row {rid} was on a damaged page and is lost")
            done.append(f"{table}: {len(rows)} row(s) read one by one")
        for row in rows:
            marks = ",".join("?" * len(row))
            new.execute(f"INSERT OR REPLACE INTO {table} VALUES ({marks})", row)
    old.close()

    def bad(text: Any) -> bool:
        try:
            json.loads(text)
            return False
        except (TypeError, ValueError):
            return True

    for key, value in new.execute("SELECT key, value FROM settings").fetchall():
        if bad(value):
            new.execute("DELETE FROM settings WHERE key = ?", (key,))
            done.append(f"setting {key!r} was damaged: back to its default {DEFAULTS.get(key)!r}")
    for sid, team, files in new.execute("SELECT id, team, files FROM submissions").fetchall():
        if bad(files):
            new.execute("DELETE FROM submissions WHERE id = ?", (sid,))
            done.append(f"submission {sid} of team {team} was damaged and is dropped: submit it again")
    for mid, entrants, result, status in new.execute("SELECT id, entrants, result, status FROM matches").fetchall():
        if bad(entrants):
            new.execute("UPDATE matches SET status = 'cancelled', error = ? WHERE id = ?",
                        ("its entrants were damaged in league.db", mid))
            done.append(f"match {mid}: its entrants were damaged; it is cancelled")
        elif result is not None and bad(result):
            new.execute("UPDATE matches SET status = 'failed', result = NULL, error = ? WHERE id = ?",
                        ("its stored result was damaged; it is played again (same match, same result)", mid))
            done.append(f"match {mid}: its result was damaged; 'league run' plays it again")
    new.close()
    for suffix in ("-wal", "-shm"):
        (root / f"league.db{suffix}").unlink(missing_ok=True)
    os.replace(fresh, db)
    if len(done) == 1:
        done.append("nothing in it was damaged")
    return done


def match_seed(league_seed: int, mid: int) -> int:
    """A match's seed: fixed by the league's seed and the match id (so a re-run is identical)."""
    return int.from_bytes(hashlib.sha256(f"{league_seed}:{mid}".encode()).digest()[:4], "big")


__all__ = ["DEFAULTS", "LeagueDamaged", "NOT_DAMAGE", "db_error", "LeagueStore", "MatchRow", "Submission", "match_seed", "repair",
           "version_of"]

"""A season: submit, schedule in a format, play on a runner, rate, and look at the standings.

The functions here tie the store, the formats, the engine, the runners and the ratings
together; ``robo-comp league`` (:mod:`robo_comp.league.cli`) is their command line.
"""
from __future__ import annotations

import hashlib
import os
import random
import stat
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

from robo_comp.errors import FieldError, UploadError
from robo_comp.league.forensics import rerun_command
from robo_comp.league import ratings, schedule
from robo_comp.league.engine import PLAY
from robo_comp.league.store import LeagueStore, MatchRow, Submission

#: The arguments ``play`` must take, after ``robot``.
PLAY_ARGS = ["width", "height", "index", "count"]


# ---------------------------------------------------------------------- submissions
def read_submission(path: str | Path) -> dict[str, str]:
    """A submission's files: one ``.py`` file, or a folder's ``extensions/*.py`` (a team made
    with ``robo-comp new-team``) or else its ``*.py``.

    A folder handed in by a team is not trusted: a symbolic link (to another team's source, or
    to a file of the organiser whose line an error would quote), a file outside the folder, a
    hard link or anything but a plain file is refused, naming only the entry in the team's own
    folder."""
    p = Path(path)
    if p.is_symlink():
        raise FieldError(f"{p}: a symbolic link; submit the team's file or folder itself")
    if p.is_file():
        files, root = [p], p.parent
    elif p.is_dir():
        root = p
        if (p / "extensions").is_symlink():
            raise FieldError(f"{p}: extensions/ is a symbolic link; a submission's files must be in its folder")
        files = sorted((p / "extensions").glob("*.py")) if (p / "extensions").is_dir() else sorted(p.glob("*.py"))
    else:
        raise FieldError(f"{p}: no such file or folder")
    if not files:
        raise FieldError(f"{p}: no Python modules to submit")
    out = {}
    for f in files:
        out[f.name] = _read_own(f, root)
    return out


def _read_own(f: Path, root: Path) -> str:
    """The text of ``f``, a plain file of the submission's own folder ``root`` (opened without
    following a link, so nothing can be swapped in between the check and the read)."""
    where = f.relative_to(root) if f.is_relative_to(root) else f.name
    if f.is_symlink():
        raise UploadError(f"{where}: a symbolic link; a submission holds its own files, not links to others",
                          file=f.name, rule="link")
    if not f.resolve().is_relative_to(root.resolve()):
        raise UploadError(f"{where}: outside the submission's folder", file=f.name, rule="link")
    try:
        fd = os.open(f, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError as e:
        raise UploadError(f"{where}: cannot be read ({e.strerror})", file=f.name, rule="link") from None
    with os.fdopen(fd, "rb") as fh:
        st = os.fstat(fh.fileno())
        if not stat.S_ISREG(st.st_mode):
            raise UploadError(f"{where}: not a plain file", file=f.name, rule="link")
        if st.st_nlink > 1:
            raise UploadError(f"{where}: a hard link to another file; submit a copy of the file",
                              file=f.name, rule="link")
        data = fh.read()
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise UploadError(f"{f.name}: not UTF-8 text", file=f.name, rule="encoding") from None


def check_submission(files: dict[str, str]) -> dict[str, dict[str, Any]]:
    """Load every module in the real sandbox through the checked contract, as an upload in a
    live match is; the modules together must advertise ``play(robot, width, height, index,
    count)``. Returns the advertised tasks; raises :class:`UploadError` with the file and
    line, or :class:`FieldError` when ``play`` is missing."""
    from robo_comp.engine.bench import Bench

    with Bench("demo_room", robots=1) as bench:
        for name, source in sorted(files.items()):
            bench.load(name, source)
        tasks = bench.tasks()
    play = tasks.get(PLAY)
    if play is None:
        raise FieldError(f"a league entry must advertise a task {PLAY!r} (it runs on every robot from the "
                         f"start): play(robot, {', '.join(PLAY_ARGS)}); the modules advertise "
                         f"{', '.join(sorted(tasks)) or 'no task'}")
    names = [a["name"] for a in play.get("args", [])]
    if len(names) != len(PLAY_ARGS):
        raise FieldError(f"task {PLAY!r} must take {len(PLAY_ARGS)} arguments ({', '.join(PLAY_ARGS)}), "
                         f"not {len(names)} ({', '.join(names) or 'none'})")
    return tasks


def submit(store: LeagueStore, team: str, files: dict[str, str], who: str) -> tuple[Submission, bool]:
    """Check and store a version of ``team``'s code; returns it and whether it is new."""
    from robo_comp.teams.tokens import check_team_name

    check_team_name(team)
    check_submission(files)
    return store.add_submission(team, files, who)


def submit_reference(store: LeagueStore, count: int = 4, who: str = "reference") -> list[Submission]:
    """Submit a reference field: the first ``count`` reference teams (at most 4), or for more,
    ``count`` entrants of known strength order: ``ref-00`` (strongest) to ``ref-NN``, the
    frontier team with handicap 0 to NN (each step: its robots start 7 s later)."""
    from robo_comp.league import reference

    if count <= len(reference.NAMES):
        chosen = [(n.replace("_", "-"), reference.source(n)) for n in reference.NAMES[:count]]
    else:
        chosen = [(f"ref-{k:02d}", reference.handicapped(reference.source("frontier"), k)) for k in range(count)]
    out = []
    for team, text in chosen:
        sub, _ = store.add_submission(team, {"play.py": text}, who)  # the shipped code passes the contract
        out.append(sub)
    return out


# ---------------------------------------------------------------------- playing
class Progress:
    """Progress of a batch of matches on ``stream``: a rich progress bar on a terminal, a line
    per match otherwise."""

    def __init__(self, total: int, stream: TextIO | None = None, label: str = "matches") -> None:
        self.total = total
        self.done = 0
        self.stream = stream if stream is not None else sys.stderr
        self.t0 = time.monotonic()
        self._bar: Any = None
        if self.stream.isatty() and total > 1:
            from rich.progress import BarColumn, MofNCompleteColumn, Progress as Bar, TimeRemainingColumn

            self._bar = Bar("[progress.description]{task.description}", BarColumn(), MofNCompleteColumn(),
                            TimeRemainingColumn(), transient=True)
            self._bar.start()
            self._task = self._bar.add_task(label, total=total)

    def step(self, text: str) -> None:
        """One match ended."""
        self.done += 1
        if self._bar is not None:
            self._bar.update(self._task, advance=1, description=text[:40])
        else:
            print(f"[{self.done}/{self.total}] {text}", file=self.stream, flush=True)

    def close(self) -> None:
        """Remove the bar."""
        if self._bar is not None:
            self._bar.stop()


def play(store: LeagueStore, runner: Any, ids: list[int] | None = None, *, stream: TextIO | None = None,
         on_match: Callable[[MatchRow], None] | None = None) -> dict[str, float]:
    """Play matches ``ids`` (default: every scheduled or failed one, and any left running by a
    run that was killed) on ``runner``, the longest expected first (:func:`schedule.longest_first`),
    store their results and move the ratings. A match
    still running when this run stops (Ctrl-C) is marked failed, to be played again. Returns
    timing figures: ``matches``, ``wall_seconds``, ``match_seconds`` (the matches' own time,
    summed) and ``league_seconds`` (storing and rating, summed)."""
    todo = ids if ids is not None else [m.id for m in store.matches()
                                        if m.status in ("scheduled", "failed", "running")]
    # the longest expected first (from the teams' earlier matches): the run ends soonest on
    # several workers; results are rated in match order whatever order they end in
    played = [(m.teams, m.scenario, m.result) for m in store.matches() if m.status == "done" and m.result]
    specs = schedule.longest_first([store.spec(mid) for mid in todo], played)
    progress = Progress(len(specs), stream)
    t0 = time.perf_counter()
    figures = {"matches": float(len(specs)), "match_seconds": 0.0, "league_seconds": 0.0, "failed": 0.0}
    for mid in todo:
        store.started(mid)

    def on_result(spec: dict[str, Any], result: dict[str, Any]) -> None:
        t = time.perf_counter()
        store.finished(spec["id"], result)
        rate_played(store)
        figures["league_seconds"] += time.perf_counter() - t
        figures["match_seconds"] += result["wall_seconds"]
        shown = "  ".join(f"{team} {score:g}" for team, score in result["scores"].items())
        progress.step(f"match {spec['id']} ({spec['scenario']}): {shown}")
        if on_match is not None:
            on_match(store.match(spec["id"]))

    def on_error(spec: dict[str, Any], message: str) -> None:
        store.failed(spec["id"], message)
        figures["failed"] += 1
        progress.step(f"match {spec['id']} failed: {message.strip().splitlines()[-1][:120]}")

    try:
        runner.run(specs, on_result, on_error)
    finally:
        progress.close()
        store.interrupted(todo)  # a stopped run's matches are played again by the next run
    figures["wall_seconds"] = time.perf_counter() - t0
    return figures


def rate_played(store: LeagueStore) -> int:
    """Move the ratings with the played ranked matches, strictly in match order: a match is
    rated only when every ranked match before it is, so the ratings do not depend on which
    worker finished first. Returns how many were rated."""
    n = 0
    current = {t: (mu, sigma) for t, (mu, sigma, _, _) in store.ratings().items()}
    for mid in store.unrated():
        m = store.match(mid)
        if m.status != "done" or m.result is None:
            break
        ranks = {t: int(r) for t, r in m.result["ranks"].items()}
        new = ratings.rate(current, ranks)
        best = min(ranks.values())
        winners = {t for t, r in ranks.items() if r == best} if len(set(ranks.values())) > 1 else set()
        if store.store_rating(m.id, new, winners):
            current.update(new)
            n += 1
        else:  # another run on this league rated it first: go on from what it stored
            current = {t: (mu, sigma) for t, (mu, sigma, _, _) in store.ratings().items()}
    return n


def rating_hold(store: LeagueStore) -> dict[str, Any] | None:
    """The match that holds up the ratings, if one does: the first unrated ranked match that is
    not played, when played matches wait behind it (``match``, ``status``, ``error``,
    ``waiting``); None otherwise."""
    waiting = store.unrated()
    for k, mid in enumerate(waiting):
        m = store.match(mid)
        if m.status != "done":
            behind = sum(1 for later in waiting[k + 1:] if store.match(later).status == "done")
            return {"match": mid, "status": m.status, "error": m.error, "waiting": behind} if behind else None
    return None


def standing(store: LeagueStore, teams: list[str] | None = None) -> list[str]:
    """Teams by leaderboard value (μ − 3σ), best first; ties (teams that have not played) in
    an order that does not favour a name: by the hash of the name."""
    r = store.ratings()
    names = teams if teams is not None else list(store.newest())
    return sorted(names, key=lambda t: (-ratings.ordinal(*r[t][:2]), hashlib.sha256(t.encode()).hexdigest()))


def run_format(store: LeagueStore, runner: Any, fmt: str, *, rounds: int | None = None, ranked: bool = True,
               teams: list[str] | None = None, stream: TextIO | None = None) -> dict[str, Any]:
    """Schedule and play a format over ``teams`` (default: every team's newest version).
    Swiss and double elimination are played round by round, each round paired from the
    results so far. Returns figures (see :func:`play`) and, for double elimination, the
    ``champion``."""
    if fmt not in schedule.FORMATS:
        raise FieldError(f"unknown format {fmt!r}; the formats are {', '.join(schedule.FORMATS)}")
    cfg = store.settings()
    known = store.newest()
    names = list(dict.fromkeys(t.strip() for t in teams if t.strip())) if teams else list(known)
    unknown = [t for t in names if t not in known]
    if unknown:
        raise FieldError(f"team(s) {', '.join(unknown)} have no submission in this league; the teams are "
                         f"{', '.join(known) or 'none yet'}")
    size = int(cfg["teams_per_match"])
    if len(names) < max(2, size):
        raise FieldError(f"a {fmt} of {size}-team matches needs at least {max(2, size)} teams with a submission; "
                         f"it has {len(names)}")
    if rounds is not None and rounds < 1:
        raise FieldError(f"rounds must be at least 1, not {rounds}")
    rng = random.Random(f"{cfg['seed']}:{fmt}:{len(store.matches())}")
    base = 1 + max((m.round for m in store.matches(fmt=fmt)), default=0)
    totals: dict[str, Any] = {"matches": 0.0, "wall_seconds": 0.0, "match_seconds": 0.0, "league_seconds": 0.0,
                              "failed": 0.0}

    def add(fig: dict[str, float]) -> None:
        for k, v in fig.items():
            totals[k] = totals.get(k, 0.0) + v

    if fmt in ("scrimmage", "round-robin"):
        plan = (schedule.scrimmage(names, rounds or 1, size, rng) if fmt == "scrimmage"
                else schedule.round_robin(names, size))
        ids = store.schedule_rounds(fmt, [(base + i, groups) for i, groups in enumerate(plan)], ranked=ranked)
        add(play(store, runner, ids, stream=stream))
        return totals
    if fmt == "swiss":
        earlier = store.matches(fmt="swiss")
        played = [frozenset(m.teams) for m in earlier]  # every meeting, repeats too
        byes = {t for rnd in {m.round for m in earlier}
                for t in set(names) - {t for m in earlier if m.round == rnd for t in m.teams}}
        for i in range(rounds or max(1, (len(names) - 1).bit_length())):
            lean = schedule.side_lean(m.teams for m in store.matches()  # as the store's balance counts them
                                      if m.status != "cancelled" and m.scenario in cfg["scenarios"])
            pairs = schedule.swiss_round(standing(store, names), played, byes, lean)
            played += [frozenset(p) for p in pairs]
            byes |= set(names) - {t for p in pairs for t in p}
            add(play(store, runner, store.schedule(fmt, base + i, pairs, ranked=ranked, per_round=True), stream=stream))
        return totals
    seeds = standing(store, names)  # double elimination, seeded by rating
    losses: dict[str, int] = {}
    rnd = base
    while (pairs := schedule.elimination_round(seeds, losses)):
        ids = store.schedule(fmt, rnd, pairs, ranked=ranked)
        add(play(store, runner, ids, stream=stream))
        for mid in ids:
            m = store.match(mid)
            if m.result is None:
                raise FieldError(f"match {mid} of the {fmt} could not be played: {m.error}")
            a, b = m.teams
            ra, rb = m.result["ranks"][a], m.result["ranks"][b]
            loser = b if (ra, seeds.index(a)) < (rb, seeds.index(b)) else a  # a tie goes to the better seed
            losses[loser] = losses.get(loser, 0) + 1
        rnd += 1
    totals["champion"] = schedule.champion(seeds, losses)
    totals["seeds"] = seeds
    return totals


# ---------------------------------------------------------------------- what people look at
def league_view(store: LeagueStore) -> dict[str, Any]:
    """The league as plain data: standings, rating history, scores per scenario, matches
    (what ``league table --json``, the HTML report and the console's leaderboard show)."""
    cfg = store.settings()
    r = store.ratings()
    newest = store.newest()
    matches = store.matches()
    played: dict[str, list[float]] = {}
    per_scenario: dict[str, dict[str, list[float]]] = {}
    rows = []
    for m in matches:
        if m.result is None:
            continue
        for team, score in m.result["scores"].items():
            played.setdefault(team, []).append(score)
            per_scenario.setdefault(m.scenario, {}).setdefault(team, []).append(score)
    for rank, team in enumerate(standing(store), start=1):
        mu, sigma, n, wins = r[team]
        scores = played.get(team, [])
        rows.append({"rank": rank, "team": team, "version": newest[team].version, "mu": round(mu, 3),
                     "sigma": round(sigma, 3), "rating": round(ratings.ordinal(mu, sigma), 3), "matches": n,
                     "wins": wins, "mean_score": round(sum(scores) / len(scores), 2) if scores else None,
                     "provisional": ratings.provisional(sigma)})
    order = {m.id: i + 1 for i, m in enumerate(m for m in matches if m.ranked and m.result is not None)}
    history = {team: [[order.get(mid, 0), round(ratings.ordinal(mu, sigma), 3)] for mid, mu, sigma in h]
               for team, h in store.history().items()}
    return {"name": cfg["name"], "root": str(store.root), "generated": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "standings": rows, "history": history, "scores": per_scenario, "held": rating_hold(store),
            "matches": [{"id": m.id, "format": m.format, "round": m.round, "scenario": m.scenario, "seed": m.seed,
                         "ranked": m.ranked, "status": m.status, "teams": m.teams,
                         "scores": (m.result or {}).get("scores", {}),
                         "forfeit": (m.result or {}).get("forfeit"),
                         "notes": match_notes(m.result, rerun_command(str(store.root), m.id)),
                         "crashes": (m.result or {}).get("crashes") or [],
                         "log": str(store.log_path(m.id).relative_to(store.root)),
                         "seconds": (m.result or {}).get("wall_seconds")} for m in matches]}


def order_free(store: LeagueStore) -> list[dict[str, Any]]:
    """The season re-rated without regard to match order (Bradley–Terry over every ranked
    match played, :func:`robo_comp.league.ratings.bradley_terry`), best first: ``rank``,
    ``team``, ``strength`` (log-strength), ``se`` (its standard error), ``matches``. For finals
    and for checking the table; the table itself stays openskill's, rated in match order."""
    played = [m.result["ranks"] for m in store.matches() if m.ranked and m.status == "done" and m.result]
    bt = ratings.bradley_terry([{t: int(r) for t, r in ranks.items()} for ranks in played])
    counts: dict[str, int] = {}
    for ranks in played:
        for t in ranks:
            counts[t] = counts.get(t, 0) + 1
    order = sorted(bt, key=lambda t: (-bt[t][0], t))
    return [{"rank": i + 1, "team": t, "strength": round(bt[t][0], 3), "se": round(bt[t][1], 3),
             "matches": counts.get(t, 0)} for i, t in enumerate(order)]


def match_notes(result: dict[str, Any] | None, rerun: str | None = None) -> list[str]:
    """What a match's report says about the limits its entrants ran into: the forfeit, the
    sandbox limits that stopped a robot, calls the call budget held back, and a match limit
    an entrant used more than half of (see docs/league.md, "Limits"); and where team code
    crashed (robot, call, line, match time), with ``rerun``, the command that plays it again."""
    if not result:
        return []
    notes = []
    for c in result.get("crashes") or []:
        call = f", last call {c['call']}" if c.get("call") else ""
        where = f"line {c['line']}" if c.get("line") else "no line of its files"
        notes.append(f"{c['team']}: robot {c['tag']}'s {c['task']} crashed at {c['t']:g} s, {where}{call}: "
                     f"{c['message']}")
    if result.get("crashes") and rerun:
        notes.append(f"reproduce it: {rerun}")
    forfeit = result.get("forfeit")
    if forfeit:
        notes.append(f"{forfeit['message']} (at {forfeit.get('t', 0):g} s)")
    names = {"events": "events", "log_bytes": "log bytes"}
    for team, hit in sorted((result.get("limits") or {}).items()):
        for message in hit.get("sandbox", []):
            notes.append(f"{team}: a robot stopped: {message}")
        if hit.get("held_calls"):
            notes.append(f"{team}: {hit['held_calls']} robot call(s) waited for the call budget")
        for name, share in sorted((hit.get("use") or {}).items()):
            if share >= 0.5:
                notes.append(f"{team}: used {share:.0%} of its {names.get(name, name)} limit")
    return notes


__all__ = ["PLAY_ARGS", "Progress", "check_submission", "league_view", "match_notes", "order_free", "play", "rate_played", "rating_hold",
           "read_submission", "run_format", "standing", "submit", "submit_reference"]

"""``robo-comp league``: a season from the first submission to the final.

::

    robo-comp league init season --reference 16          # a league folder, a 16-entrant reference field
    robo-comp league submit season rescuers ./rescuers    # a team's code (checked like an upload)
    robo-comp league run season --format round-robin     # schedule and play (local processes)
    robo-comp league run season --format swiss --rounds 4 --ray auto
    robo-comp league table season                        # the leaderboard (--json for data; ? = provisional)
    robo-comp league table season --order-free           # and a Bradley-Terry re-rating of the season
    robo-comp league report season season/report.html    # one static page with plots and each match's limits
    robo-comp league cancel season 12                    # a match that cannot be played: out
    robo-comp league repair season                       # a damaged league.db: keep what can be read
    robo-comp league rerun season 12                     # play match 12 again here (a crash: the same crash)
    robo-comp league compare ./v1 ./v2                   # is v2 better than v1? (paired by seed, 95 % interval)
    robo-comp league compare rescuers@1a2b rescuers --league season   # two submissions, the league's opponents

Ctrl-C stops a run at once; 'league run' again plays what it stopped. One run per league at a
time. An entrant over its limits in a match forfeits that match. See docs/league.md.
"""
from __future__ import annotations

import argparse
import getpass
import json
import os
import sys
from pathlib import Path
from typing import Any

from robo_comp.errors import FieldError

DESCRIPTION = __doc__


def add_parser(sub: Any) -> None:
    """Add ``league`` and its subcommands to the ``robo-comp`` parser."""
    from robo_comp.league.schedule import FORMATS

    p = sub.add_parser("league", help="ranked scrimmages and tournaments over many matches (docs/league.md)",
                       description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    lsub = p.add_subparsers(dest="league_command", required=True, metavar="COMMAND")

    i = lsub.add_parser("init", help="start a league in a folder")
    i.add_argument("league", metavar="LEAGUE", help="the league's folder (created)")
    i.add_argument("--name", help="the league's name (shown in the table and report)")
    i.add_argument("--scenarios", help="comma-separated scenario pool: bundled names, files, or "
                   "generated:SEED[:DIFFICULTY[:TEAMS]] (default: office,generated:1:0.5)")
    i.add_argument("--generated", type=int, metavar="N", help="add N generated scenarios (seeds 1..N) to the pool")
    i.add_argument("--difficulty", type=float, default=0.5, help="difficulty of the --generated scenarios (0..1)")
    i.add_argument("--robots", type=int, help="robots per team (default 4)")
    i.add_argument("--seconds", type=float, help="match length in simulated seconds (default 300)")
    i.add_argument("--teams-per-match", type=int, help="teams in one match (default 2)")
    i.add_argument("--seed", type=int, help="the league's seed (every match's seed follows from it)")
    i.add_argument("--rules", metavar="MODULE:OBJECT",
                   help="scoring rules plugin for every match instead of the default search-and-rescue rules "
                        "(as core --rules; the module must be importable where matches are played)")
    i.add_argument("--debug-replay", choices=("team", "everyone"),
                   help="who sees a team's debug drawing in the match replays: the team (default) or everyone")
    i.add_argument("--reference", type=int, default=0, metavar="N",
                   help="submit a reference field of N entrants (4 or fewer: the reference teams; more: "
                        "ref-00..ref-NN of known strength order)")
    i.set_defaults(func=_init)

    s = lsub.add_parser("submit", help="store a version of a team's code (checked like an upload)")
    s.add_argument("league", metavar="LEAGUE")
    s.add_argument("team", metavar="TEAM", help="team name (lowercase letters, digits, - and _)")
    s.add_argument("path", metavar="PATH", help="a .py file, or a team folder (its extensions/*.py)")
    s.add_argument("--who", default=None, help="who submits (default: the login name)")
    s.set_defaults(func=_submit)

    r = lsub.add_parser("run", help="schedule a format and play it (or play what is scheduled)")
    r.add_argument("league", metavar="LEAGUE")
    r.add_argument("--format", choices=FORMATS, help="the format to schedule and play; without it, play the "
                   "scheduled and failed matches")
    r.add_argument("--rounds", type=int, help="rounds (scrimmage: each team plays once a round; swiss)")
    r.add_argument("--teams", help="comma-separated teams (default: every team with a submission)")
    r.add_argument("--unranked", action="store_true", help="test matches: played and logged, ratings untouched")
    r.add_argument("--workers", type=int, default=None, help="local processes (default: the CPU count)")
    r.add_argument("--ray", metavar="ADDRESS", help="play on a Ray cluster: auto (this machine's cluster), "
                   "an address such as 10.0.0.1:6379, or local (start one here)")
    from robo_comp.sandbox import oswall

    oswall.add_option(r)
    r.set_defaults(func=_run)

    t = lsub.add_parser("table", help="the leaderboard (μ − 3σ)")
    t.add_argument("league", metavar="LEAGUE")
    t.add_argument("--json", action="store_true", help="print the league as JSON (standings, history, matches)")
    t.add_argument("--order-free", action="store_true", help="also re-rate the season without regard to match "
                   "order (Bradley-Terry over every ranked result; for finals)")
    t.set_defaults(func=_table)

    o = lsub.add_parser("report", help="write one static HTML page: table, rating plots, score plots, matches")
    o.add_argument("league", metavar="LEAGUE")
    o.add_argument("out", metavar="OUT.html")
    o.set_defaults(func=_report)

    c = lsub.add_parser("cancel", help="take scheduled or failed matches out of the league (never played or rated)")
    c.add_argument("league", metavar="LEAGUE")
    c.add_argument("ids", metavar="MATCH", type=int, nargs="+", help="match ids (see 'league table --json')")
    c.add_argument("--why", default="cancelled by the organiser", help="the reason, kept with the match")
    c.set_defaults(func=_cancel)

    f = lsub.add_parser("repair", help="recover a damaged league.db: keep what can be read, play damaged matches again")
    f.add_argument("league", metavar="LEAGUE")
    f.set_defaults(func=_repair)

    rr = lsub.add_parser("rerun", help="play one league match again on this machine (the same seed, scenario "
                         "and code: a crash shows again, with its traceback)")
    rr.add_argument("league", metavar="LEAGUE")
    rr.add_argument("match", metavar="MATCH", type=int)
    rr.add_argument("--team", action="append", default=[], metavar="TEAM=PATH",
                    help="play TEAM with the code in PATH (a folder or .py) instead of its submission")
    rr.add_argument("--log", metavar="OUT.log", help="where the match's log goes (default: rerun-MATCH.log here)")
    rr.set_defaults(func=_rerun)

    cp = lsub.add_parser("compare", help="play two versions of a team against the same opponents, scenarios and "
                         "seeds; print the mean score difference with its 95 %% confidence interval",
                         description="A and B are folders or .py files (opponents: reference teams), or with "
                         "--league two submissions TEAM@VERSION (or TEAM: its newest) of that league (opponents: "
                         "the league's other teams, its scenarios, robots and match length).")
    cp.add_argument("a", metavar="A")
    cp.add_argument("b", metavar="B")
    cp.add_argument("--league", help="compare two submissions of this league")
    cp.add_argument("--against", help="comma-separated opponents: reference teams (frontier, explorer, "
                    "random_walker, sitter), or with --league its teams (default: frontier,explorer; with "
                    "--league: up to 3 of its other teams)")
    cp.add_argument("--scenarios", help="comma-separated scenarios (default: office; with --league its pool)")
    cp.add_argument("--seeds", type=int, default=4, help="seeds per opponent and scenario (default 4)")
    cp.add_argument("--robots", type=int, help="robots per team (default 4, or the league's)")
    cp.add_argument("--seconds", type=float, help="match length (default 120, or the league's)")
    cp.add_argument("--workers", type=int, default=None, help="local processes (default: the CPU count)")
    cp.add_argument("--out", default="compare", help="folder for the match logs (default ./compare)")
    cp.set_defaults(func=_compare, ray=None)

    for sp in (i, s, r, t, o, c, rr, cp):
        sp.set_defaults(func=_guarded(sp.get_default("func")))
    p.set_defaults(func=lambda args: p.print_help() or 2)


def _guarded(func: Any) -> Any:
    """``func`` with SQLite's own errors turned into a sentence with the way out (instead of a
    traceback): ``league repair`` for a damaged ``league.db``, waiting for a busy one."""
    import functools
    import sqlite3

    @functools.wraps(func)
    def run(args: argparse.Namespace) -> int:
        try:
            return int(func(args) or 0)
        except sqlite3.DatabaseError as e:
            from robo_comp.league.store import db_error

            raise db_error(Path(args.league), e, f"SQLite says {e}") from None

    return run


def _repair(args: argparse.Namespace) -> int:
    from robo_comp.league.store import repair

    for line in repair(args.league):
        print(line)
    return 0


def _store(args: argparse.Namespace, create: bool = False) -> Any:
    from robo_comp.league.store import LeagueStore

    return LeagueStore(args.league, create=create)


def _init(args: argparse.Namespace) -> int:
    from robo_comp.league import season

    root = Path(args.league)
    if (root / "league.db").exists():
        raise FieldError(f"{root} already holds a league; submit to it or run it")
    changes: dict[str, Any] = {}
    if args.rules:
        from robo_comp.plugins.manager import load_rules

        load_rules(args.rules)  # refused here, in a sentence, rather than at the first match
    for key in ("name", "robots", "seconds", "teams_per_match", "seed", "debug_replay", "rules"):
        v = getattr(args, key)
        if v is not None:
            changes[key] = v
    if changes.get("robots", 1) < 1 or changes.get("seconds", 1) <= 0 or changes.get("teams_per_match", 2) < 2:
        raise FieldError("robots must be at least 1, seconds above 0 and teams per match at least 2")
    if args.reference < 0 or args.generated is not None and args.generated < 0:
        raise FieldError("--reference and --generated take a count of 0 or more")
    size = int(changes.get("teams_per_match", 2))
    pool = [s.strip() for s in args.scenarios.split(",") if s.strip()] if args.scenarios else None
    if args.generated:
        pool = (pool or ["office"]) + [f"generated:{k}:{args.difficulty:g}:{size}" for k in range(1, args.generated + 1)]
    if pool is None and size != 2:
        raise FieldError(f"the default scenarios have start zones for 2 teams; give --scenarios (or --generated) "
                         f"for {size}-team matches, e.g. --scenarios generated:1:0.5:{size}")
    if pool is not None:
        from robo_comp.league.engine import load_match_scenario

        checked = []
        for spec in pool:  # a bad pool fails now, not in the middle of a season
            scenario = load_match_scenario(spec)
            if len(scenario.teams) < size:
                raise FieldError(f"scenario {spec!r} has start zones for {len(scenario.teams)} teams, not the "
                                 f"{size} of a match in this league")
            # a scenario file is kept by its full path: matches are played from any folder, on any worker
            checked.append(str(Path(spec).resolve()) if Path(spec).is_file() else spec)
        changes["scenarios"] = checked
    with _store(args, create=True) as store:
        store.configure(**changes)
        subs = season.submit_reference(store, args.reference) if args.reference else []
        cfg = store.settings()
    print(f"league {cfg['name']!r} in {root}: scenarios {', '.join(cfg['scenarios'])}; {cfg['robots']} robots "
          f"per team, {cfg['seconds']:g} s matches, {cfg['teams_per_match']} teams per match")
    if subs:
        print(f"reference field: {', '.join(s.team for s in subs)}")
    return 0


def _submit(args: argparse.Namespace) -> int:
    from robo_comp.league import season

    files = season.read_submission(args.path)
    with _store(args) as store:
        sub, new = season.submit(store, args.team, files, args.who or _login())
    what = "stored" if new else "already stored (same files)"
    print(f"{sub.team} version {sub.version} {what}: {', '.join(sorted(sub.files))}")
    return 0


def _login() -> str:
    """Who submits when ``--who`` is not given: the login name (or "unknown" where there is none)."""
    try:
        return getpass.getuser()
    except (KeyError, OSError):
        return "unknown"


def runner_for(args: argparse.Namespace) -> Any:
    """The runner the arguments ask for: Ray with ``--ray``, else local processes."""
    from robo_comp.league.runner import LocalRunner, RayRunner

    if args.ray:
        from robo_comp.sandbox import oswall

        # the cluster's workers do not inherit this environment: the OS layer's setting goes with the job
        setting = os.environ.get(oswall.ENV)
        return RayRunner(args.ray, **({"runtime_env": {"env_vars": {oswall.ENV: setting}}} if setting else {}))
    return LocalRunner(args.workers or os.cpu_count() or 1)


def _run(args: argparse.Namespace) -> int:
    from robo_comp.league import season

    if not args.format and (args.teams or args.rounds is not None or args.unranked):
        raise FieldError("--teams, --rounds and --unranked choose what a --format schedules; without "
                         "--format, 'league run' plays the matches already scheduled")
    from robo_comp.league.runner import Stopped
    from robo_comp.sandbox import oswall

    if args.ray:  # the workers' machines run the team code: they get the organiser's setting
        oswall.choose(args.os_sandbox)
    else:  # this machine does: a run that cannot wall team code stops before its first match
        oswall.at_start("league run", args.os_sandbox)
    with _store(args) as store:
        store.lock()  # one run per league; the kernel drops it however this process ends
        runner = runner_for(args)
        try:
            if args.format:
                teams = [t.strip() for t in args.teams.split(",")] if args.teams else None
                fig = season.run_format(store, runner, args.format, rounds=args.rounds, ranked=not args.unranked,
                                        teams=teams)
            else:
                fig = season.play(store, runner)
        except (Stopped, KeyboardInterrupt) as e:
            running, waiting = (e.running, e.waiting) if isinstance(e, Stopped) else (0, 0)
            print(f"stopped: {running} match{'es' if running != 1 else ''} stopped while playing, {waiting} not "
                  f"started; 'robo-comp league run {args.league}' plays them (the same matches, the same results)",
                  file=sys.stderr)
            return 130
        finally:
            try:
                runner.close()
            except KeyboardInterrupt:
                pass
        n = int(fig["matches"])
        print(f"played {n} match{'es' if n != 1 else ''} in {fig['wall_seconds']:.1f} s"
              + (f", {int(fig['failed'])} failed (run again to retry)" if fig.get("failed") else ""))
        if fig.get("champion"):
            print(f"champion: {fig['champion']}")
        print(_text(store))
    return 1 if fig.get("failed") else 0


def _cancel(args: argparse.Namespace) -> int:
    with _store(args) as store:
        for mid in args.ids:
            store.cancel(mid, args.why)
            print(f"match {mid} cancelled: it will not be played or rated")
    return 0


def _text(store: Any) -> str:
    from robo_comp.league.report import standings_text
    from robo_comp.league.season import league_view

    return standings_text(league_view(store))


def _table(args: argparse.Namespace) -> int:
    from robo_comp.league.season import league_view

    from robo_comp.league.season import order_free

    with _store(args) as store:
        if args.json:
            view = league_view(store)
            if args.order_free:
                view["order_free"] = order_free(store)
            json.dump(view, sys.stdout, indent=1)
            print()
        else:
            print(_text(store))
            if args.order_free:
                rows = order_free(store)
                print("\nOrder-free re-rating (Bradley-Terry over every ranked result; strength ± standard error):")
                for r in rows:
                    print(f"{r['rank']:>3}  {r['team']:<24} {r['strength']:+.2f} ± {r['se']:.2f}  ({r['matches']} matches)")
    return 0


def _report(args: argparse.Namespace) -> int:
    from robo_comp.league.report import write_report
    from robo_comp.league.season import league_view

    with _store(args) as store:
        view = league_view(store)
        out = Path(args.out)
        root = store.root.resolve()
    # the match logs are linked relative to the page
    rel = Path(os.path.relpath(root, out.resolve().parent))
    for m in view["matches"]:
        m["log"] = str(rel / m["log"])
    write_report(out, view)
    print(f"wrote {out} ({len(view['standings'])} teams, {len(view['matches'])} matches)")
    return 0


def _code(store: Any, spec: str) -> tuple[str, dict[str, str]]:
    """``TEAM@VERSION`` (or ``TEAM``: its newest) of a league: the team and its files."""
    team, _, version = spec.partition("@")
    subs = store.submissions(team)
    if not subs:
        raise FieldError(f"the league has no submission of team {team!r}")
    if not version:
        return team, store.newest()[team].files
    chosen = [x for x in subs if x.version.startswith(version)]
    if len(chosen) != 1:
        raise FieldError(f"team {team} has {'no' if not chosen else 'more than one'} version starting with "
                         f"{version!r}; its versions: {', '.join(x.version for x in subs)}")
    return team, chosen[0].files


def _compare(args: argparse.Namespace) -> int:
    from robo_comp.league import compare, reference, season

    seeds = list(range(1, max(1, args.seeds) + 1))
    if args.league:
        with _store(args) as store:
            team_a, a = _code(store, args.a)
            team_b, b = _code(store, args.b)
            cfg = store.settings()
            newest = store.newest()
            names = ([x.strip() for x in args.against.split(",") if x.strip()] if args.against
                     else [t for t in sorted(newest) if t not in (team_a, team_b)][:3])
            missing = [x for x in names if x not in newest]
            if missing:
                raise FieldError(f"the league has no team {', '.join(missing)}")
            opponents = {x: newest[x].files for x in names}
        scenarios = args.scenarios.split(",") if args.scenarios else list(cfg["scenarios"])
        robots, seconds = args.robots or cfg["robots"], args.seconds or cfg["seconds"]
    else:
        a, b = season.read_submission(args.a), season.read_submission(args.b)
        for files in (a, b):
            season.check_submission(files)
        names = [x.strip() for x in (args.against or "frontier,explorer").split(",") if x.strip()]
        try:
            opponents = {x.replace("_", "-"): {"play.py": reference.source(x.replace("-", "_"))} for x in names}
        except KeyError as e:
            raise FieldError(str(e.args[0])) from None
        scenarios = args.scenarios.split(",") if args.scenarios else ["office"]
        robots, seconds = args.robots or 4, args.seconds or 120.0
    if not opponents:
        raise FieldError("no opponent to play against: give --against")
    n = len(opponents) * len(scenarios) * len(seeds)
    print(f"playing {2 * n} matches: A and B each against {', '.join(opponents)} on {', '.join(scenarios)}, "
          f"seeds {seeds[0]}..{seeds[-1]} ({robots} robots, {seconds:g} s)", file=sys.stderr, flush=True)
    runner = runner_for(args)
    try:
        result = compare.compare(a, b, opponents, scenarios, seeds, robots=robots, seconds=seconds,
                                 out=Path(args.out), runner=runner)
    finally:
        runner.close()
    print(compare.report(result))
    return 0


def _rerun(args: argparse.Namespace) -> int:
    from robo_comp.league import season
    from robo_comp.league.engine import play_match
    from robo_comp.league.forensics import crash_text, rerun_command

    with _store(args) as store:
        spec = store.spec(args.match)
    for pair in args.team:
        team, sep, path = pair.partition("=")
        entrant = next((e for e in spec["entrants"] if e["team"] == team), None)
        if not sep or entrant is None:
            raise FieldError(f"--team wants TEAM=PATH with a team of match {args.match} "
                             f"({', '.join(e['team'] for e in spec['entrants'])}), not {pair!r}")
        entrant["files"] = season.read_submission(path)
        entrant["version"] = "local"
    spec["log"] = args.log or f"rerun-{args.match}.log"
    result = play_match(spec)
    print(f"match {args.match} played again ({spec['scenario']}, seed {spec['seed']}): "
          + ", ".join(f"{t} {s:g}" for t, s in result["scores"].items()))
    for c in result.get("crashes") or []:
        print(crash_text(c, seed=spec["seed"], scenario=spec["scenario"],
                         command=rerun_command(args.league, args.match)))
    if not result.get("crashes"):
        print("no team code crashed in this match")
    print(f"watch it: robo-comp web --replay {spec['log']}")
    return 0


__all__ = ["add_parser", "runner_for"]

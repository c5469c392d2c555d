"""The league's figures (issue 15): throughput and scaling, rating quality, league overhead.

    .venv/bin/python bench/bench_league.py [--matches 16] [--skip-ray] [--skip-throughput] [--quality-rounds 30] [--quality-format swiss]
    .venv/bin/python bench/bench_league.py --skip-throughput     # the documented season's rating quality only

1. **Throughput.** ``--matches`` league matches of 5 simulated minutes, 8 robots (two teams of
   four, frontier against explorer and the other reference teams) on ``office``, played by a
   real league (SQLite store, ratings) with one local worker, then two local workers, then on a
   local Ray cluster of two nodes (two raylets of one CPU each, started by ``ray start --head``
   and a second ``ray start``, each node a session of its own as on two machines). Printed:
   matches per hour per core, the speed-up over one worker and the scaling efficiency
   (speed-up ÷ workers), the CPU time a match cost (worker and sandboxes: the same on a loaded
   machine) and how many cores the run kept busy, the load average, and whether every match
   gave the same result (digest of its event log) everywhere. ``--rounds N`` plays it N times
   over (1, 2 workers, Ray in turn). Then, on paper: what a 500-team scrimmage season needs.
2. **Overhead.** Per match, the league's own time (building specs, scheduling, storing,
   rating) against the match's time, from the one-worker run.
3. **Rating quality.** 16 entrants of known strength order (``ref-00`` .. ``ref-15``: the
   frontier team with handicap 0..15), ranked rounds (8 two-team matches each, short matches on
   demo_room): random scrimmage pairs, or with ``--quality-format swiss`` neighbours in the
   standing; after each round Kendall's τ between the leaderboard and the true order. Printed:
   the matches after which τ first reaches 0.9 and after which it stays there, whether it held
   over the last quarter (yes/no), and τ of the order-free re-rating (Bradley–Terry) at the end.
   ``--quality-seconds`` and ``--quality-late`` set the match length and the handicap step; the
   defaults (120 s, 7 s, 30 rounds) are the season docs/league.md documents.
4. **Fair play** (issue 26, ``--fair``): a hostile entrant that steers by every entropy source
   (tests/league_entrants/entropy.py) played 10 times in one process, 10 times on one worker,
   on two workers and on a local two-node Ray cluster: the digests of the 10 x 4 event logs;
   then the flooding entrant (tests/league_entrants/flood.py, 499 pictures between two moves)
   against a normal match, each in a fresh process: wall time and the worker's peak memory;
   then a round robin with the flooding entrant in it (the season goes on).
"""
from __future__ import annotations

import argparse
import contextlib
import pathlib
import shutil
import sys
import tempfile
import time
from collections.abc import Iterator

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from robo_comp.league import season  # noqa: E402
from robo_comp.league.ratings import kendall_tau  # noqa: E402
from robo_comp.league.runner import LocalRunner, RayRunner  # noqa: E402
from robo_comp.league.store import LeagueStore  # noqa: E402


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextlib.contextmanager
def two_node_ray() -> Iterator[RayRunner]:
    """A runner on a two-node Ray cluster of one CPU each on this machine, as ``ray start --head``
    and a second ``ray start`` make it, on loopback, each node a session of its own as on two
    machines: under Linux's autogroup scheduling the processes of one session share one CPU
    share, so two nodes started from this process (``ray.cluster_utils.Cluster``) played as one
    CPU on a machine shared with others (1.05x for 1 -> 2 nodes in one run). Its processes are
    ended afterwards (by their process groups: never ``ray stop``, which ends every Ray here)."""
    import os
    import signal
    import subprocess

    ray_cli = str(pathlib.Path(sys.executable).with_name("ray"))
    address = f"127.0.0.1:{_free_port()}"
    groups: list[int] = []

    def start(*args: str) -> None:
        ports = [a for name in ("--dashboard-agent-listen-port", "--dashboard-agent-grpc-port",
                                "--metrics-export-port", "--runtime-env-agent-port") for a in (name, str(_free_port()))]
        p = subprocess.Popen([ray_cli, "start", *args, "--num-cpus", "1", "--node-ip-address", "127.0.0.1",
                              "--disable-usage-stats", *ports], start_new_session=True,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        groups.append(p.pid)  # the node's daemons stay in this process group
        _, err = p.communicate(timeout=300)
        if p.returncode != 0:
            raise RuntimeError(f"ray start {' '.join(args)} failed: {err[-2000:]}")

    try:
        start("--head", "--port", address.rsplit(":", 1)[1], "--include-dashboard", "false")
        start("--address", address)
        runner = RayRunner(address)
        try:
            yield runner
        finally:
            runner.close()
    finally:
        for sig in (signal.SIGTERM, signal.SIGKILL):
            for g in groups:
                with contextlib.suppress(ProcessLookupError, PermissionError):
                    os.killpg(g, sig)
            time.sleep(2.0)


FULL = {"scenarios": ["office"], "robots": 4, "seconds": 300}
SHORT = {"scenarios": ["demo_room"], "robots": 2, "seconds": 60}


def throughput(root: pathlib.Path, runner, matches: int, label: str) -> dict:
    """Play ``matches`` full matches (scrimmage rounds of the 4 reference teams) on ``runner``."""
    with LeagueStore(root / label, create=True) as store:
        store.configure(**FULL)
        season.submit_reference(store, 4)
        t0 = time.perf_counter()
        ids = []
        for rnd in range((matches + 1) // 2):
            pairs = [["frontier", "explorer"], ["random-walker", "sitter"]] if rnd % 2 == 0 else \
                [["frontier", "random-walker"], ["explorer", "sitter"]]
            ids += store.schedule("scrimmage", rnd + 1, pairs)
        ids = ids[:matches]
        sched = time.perf_counter() - t0
        fig = season.play(store, runner, ids, stream=open("/dev/null", "w"))
        done = [m for m in store.matches() if m.result]
        digests = {m.id: m.result["digest"] for m in done}
        cpu = [float(m.result.get("cpu_seconds", 0.0)) for m in done]
    fig["schedule_seconds"] = sched
    fig["digests"] = digests
    fig["cpu_per_match"] = sum(cpu) / max(1, len(cpu))
    return fig


ENTRANTS = ROOT / "tests" / "league_entrants"


def hostile_spec(i: int, root: pathlib.Path) -> dict:
    """The hostile-entropy match (the same spec every time; only where its log goes differs)."""
    from robo_comp.league import reference

    return {"id": i, "scenario": "demo_room", "seed": 5, "seconds": 60, "robots": 2,
            "entrants": [{"team": "entropy", "version": "e", "files": {"play.py": (ENTRANTS / "entropy.py").read_text()}},
                         {"team": "frontier", "version": "f", "files": {"play.py": reference.source("frontier")}}],
            "log": str(root / f"hostile-{i}.log")}


def replays(runner, root: pathlib.Path, label: str, n: int = 10) -> list[str]:
    """``n`` plays of the hostile match on ``runner``; the digests of their logs."""
    got: dict[int, str] = {}
    errors: list[str] = []
    specs = [hostile_spec(i, root / label) for i in range(n)]
    (root / label).mkdir(parents=True, exist_ok=True)
    runner.run(specs, lambda sp, r: got.__setitem__(sp["id"], r["digest"]), lambda sp, e: errors.append(e))
    if errors:
        raise RuntimeError(errors[0])
    return [got[i] for i in range(n)]


ONE_MATCH = """
import json, resource, sys, time
sys.path.insert(0, {root!r})
from robo_comp.league import reference
from robo_comp.league.engine import play_match
files = {files!r}
t0 = time.perf_counter()
res = play_match({{"id": 1, "scenario": "office", "seed": 3, "seconds": 300, "robots": 4, "log": {log!r},
                  "entrants": [{{"team": t, "version": t, "files": {{"play.py": files[t]}}}} for t in files]}})
print(json.dumps({{"wall": time.perf_counter() - t0, "rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "scores": res["scores"], "forfeit": res["forfeit"], "limits": res["limits"],
                  "log_mib": __import__("os").path.getsize({log!r}) / 2**20}}))
"""


def one_match(root: pathlib.Path, label: str, a: str, b: str) -> dict:
    """A full match (office, 4 robots a team, 300 s) in a fresh process: its wall time, the
    process's peak memory, the log's size."""
    import json
    import subprocess

    from robo_comp.league import reference

    def src(name: str) -> str:
        path = ENTRANTS / f"{name}.py"
        return path.read_text() if path.exists() else reference.source(name)

    code = ONE_MATCH.format(root=str(ROOT), files={a: src(a), b: src(b)}, log=str(root / f"{label}.log"))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=1800)
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-2000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def fair_figures(root: pathlib.Path, args: argparse.Namespace) -> None:
    """Issue 26's figures: replays of a hostile match everywhere, a flooding entrant's cost."""
    from robo_comp.league.engine import play_match

    print("== fair play: the hostile-entropy match (demo_room, 60 s, 2 robots a team), 10 plays each way")
    here = []
    for i in range(10):
        spec = hostile_spec(i, root)
        here.append(play_match(spec)["digest"])
    with LocalRunner(2) as two:
        ways = {"in one process": here, "1 worker": replays(LocalRunner(1), root, "one"),
                "2 workers": replays(two, root, "two")}
    if not args.skip_ray:
        with two_node_ray() as runner:
            ways["Ray, 2 nodes"] = replays(runner, root, "ray")
    every = {d for v in ways.values() for d in v}
    for way, digests in ways.items():
        print(f"{way:>15}: {len(set(digests))} distinct log(s) in {len(digests)} plays ({digests[0][:12]})")
    print(f"all {sum(len(v) for v in ways.values())} logs byte-identical: {len(every) == 1}")
    print("== fair play: a flooding entrant (499 pictures between two moves) against a normal match "
          "(office, 300 s, 4 robots a team, a fresh process each)")
    normal = one_match(root, "normal", "frontier", "explorer")
    flood = one_match(root, "flood", "flood", "explorer")
    for label, f in (("normal (frontier v explorer)", normal), ("flood v explorer", flood)):
        print(f"{label:>30}: {f['wall']:.1f} s, worker peak {f['rss_mib']:.0f} MiB, log {f['log_mib']:.2f} MiB, "
              f"scores {f['scores']}, forfeit {f['forfeit']}")
    print(f"flood / normal: wall {flood['wall'] / normal['wall']:.2f}x, memory {flood['rss_mib'] / normal['rss_mib']:.2f}x "
          f"(target < 2x); calls held by the call budget: {flood['limits']['flood']['held_calls']}")
    with LeagueStore(root / "season-flood", create=True) as store:
        store.configure(**SHORT)
        season.submit_reference(store, 3)
        store.add_submission("flood", {"play.py": (ENTRANTS / "flood.py").read_text()}, "bench")
        with LocalRunner(2) as runner:
            fig = season.run_format(store, runner, "round-robin", stream=open("/dev/null", "w"))
        done = sum(1 for m in store.matches() if m.status == "done")
        print(f"round robin with the flooding entrant: {done} of {int(fig['matches'])} matches played, "
              f"{int(fig['failed'])} failed; table: {' > '.join(season.standing(store))}")


def quality(root: pathlib.Path, rounds: int, workers: int, fmt: str = "scrimmage", seconds: float = 60,
            late: float = 4) -> tuple[list[tuple[int, float]], float]:
    """τ of the leaderboard against the true order after each round of 16 entrants: scrimmage
    rounds, or (``fmt="swiss"``) one scrimmage round and then rounds of the league's own Swiss
    format (``league run --format swiss --rounds 1``: neighbours in the standing who have not
    met; rematches once no pairing avoids them)."""
    import re

    from robo_comp.league import reference
    from robo_comp.league.ratings import bradley_terry

    curve = []
    with LeagueStore(root / f"quality-{fmt}", create=True) as store:
        store.configure(**dict(SHORT, seconds=seconds))
        base = re.sub(r"^LATE = \d+(\.\d+)?", f"LATE = {late:g}", reference.source("frontier"), count=1, flags=re.M)
        truth = []
        for k in range(16):  # ref-00 (no handicap) is the strongest
            store.add_submission(f"ref-{k:02d}", {"play.py": reference.handicapped(base, k)}, "bench")
            truth.append(f"ref-{k:02d}")
        played = 0
        with LocalRunner(workers) as runner:
            for i in range(rounds):
                chosen = "swiss" if fmt == "swiss" and i > 0 else "scrimmage"
                fig = season.run_format(store, runner, chosen, rounds=1, stream=open("/dev/null", "w"))
                played += int(fig["matches"])
                curve.append((played, kendall_tau(season.standing(store), truth)))
        bt = bradley_terry([m.result["ranks"] for m in store.matches() if m.result])
        bt_tau = kendall_tau(sorted(bt, key=lambda t: -bt[t][0]), truth)
    return curve, bt_tau


def _load() -> str:
    import os

    return "/".join(f"{x:.1f}" for x in os.getloadavg())


def _cpu_line(fig: dict, workers: int) -> str:
    """CPU a match (worker and sandboxes), how many cores the run kept busy on average, and how
    much of the workers' time went to playing (the rest: starting, waiting for the last match)."""
    busy = fig["cpu_per_match"] * fig["matches"] / fig["wall_seconds"]
    playing = fig["match_seconds"] / (workers * fig["wall_seconds"])
    return f"CPU {fig['cpu_per_match']:.2f} s a match, {busy:.2f} cores busy, workers playing {playing:.0%} of the run"


def throughput_figures(root: pathlib.Path, args: argparse.Namespace) -> None:
    """Throughput on 1 and 2 local workers (and Ray), the season on paper, and the overhead."""
    speedups: dict[str, list[float]] = {"2 workers": [], "Ray, 2 nodes": []}
    for rnd in range(args.rounds):
        tag = f"[{rnd + 1}/{args.rounds}] " if args.rounds > 1 else ""
        print(f"== {tag}throughput: {args.matches} matches of 300 s, 2 teams x 4 robots, office (load {_load()})")
        one = throughput(root, LocalRunner(1), args.matches, f"one-{rnd}")
        rate1 = 3600 * one["matches"] / one["wall_seconds"]
        print(f"1 worker : {one['wall_seconds']:.1f} s, {rate1:.0f} matches/hour/core "
              f"({one['match_seconds'] / one['matches']:.2f} s a match), {_cpu_line(one, 1)} (load {_load()})")
        with LocalRunner(2) as runner:
            two = throughput(root, runner, args.matches, f"two-{rnd}")
        rate2 = 3600 * two["matches"] / two["wall_seconds"]
        speedups["2 workers"].append(rate2 / rate1)
        print(f"2 workers: {two['wall_seconds']:.1f} s, {rate2:.0f} matches/hour, speed-up {rate2 / rate1:.2f}x, "
              f"efficiency {rate2 / rate1 / 2:.0%}, {_cpu_line(two, 2)}, CPU a match "
              f"{two['cpu_per_match'] / one['cpu_per_match']:.2f}x one worker's; same results: "
              f"{two['digests'] == one['digests']} (load {_load()})")
        if not args.skip_ray:
            with two_node_ray() as ray_runner:
                ray_fig = throughput(root, ray_runner, args.matches, f"ray-{rnd}")
            rate_r = 3600 * ray_fig["matches"] / ray_fig["wall_seconds"]
            speedups["Ray, 2 nodes"].append(rate_r / rate1)
            print(f"Ray, 2 nodes x 1 CPU: {ray_fig['wall_seconds']:.1f} s, {rate_r:.0f} matches/hour, speed-up "
                  f"{rate_r / rate1:.2f}x, efficiency {rate_r / rate1 / 2:.0%}, {_cpu_line(ray_fig, 2)}; same "
                  f"results: {ray_fig['digests'] == one['digests']} (load {_load()})")
    if args.rounds > 1:
        for way, got in speedups.items():
            if got:
                print(f"{way}: speed-up over 1 worker {min(got):.2f}x .. {max(got):.2f}x (median "
                      f"{sorted(got)[len(got) // 2]:.2f}x) over {len(got)} runs")
    per_match = one["match_seconds"] / one["matches"]
    season_matches = 500 * 40 // 2
    print(f"on paper: a 500-team scrimmage season, 40 matches a team = {season_matches:,} matches x "
          f"{per_match:.1f} s = {season_matches * per_match / 3600:.0f} core-hours "
          f"({season_matches * per_match / 3600 / 64:.1f} h on 64 cores)")
    overhead = one["wall_seconds"] - one["match_seconds"] + one["schedule_seconds"]
    print(f"== overhead: league {1000 * overhead / one['matches']:.1f} ms a match (storing and rating "
          f"{1000 * one['league_seconds'] / one['matches']:.1f} ms) = "
          f"{overhead / one['match_seconds']:.2%} of the match (target < 2%)")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--matches", type=int, default=16, help="full matches per throughput run (default 16)")
    ap.add_argument("--skip-ray", action="store_true", help="no Ray cluster run")
    ap.add_argument("--rounds", type=int, default=1, help="throughput runs (1 worker, 2 workers, Ray in turn)")
    ap.add_argument("--skip-throughput", action="store_true", help="only the rating-quality run")
    ap.add_argument("--quality-rounds", type=int, default=30, help="rounds of the rating-quality run")
    ap.add_argument("--quality-format", choices=("scrimmage", "swiss"), default="scrimmage",
                    help="random pairs every round, or neighbours in the standing after a first random round")
    ap.add_argument("--quality-seconds", type=float, default=120, help="match length of the rating-quality run")
    ap.add_argument("--quality-late", type=float, default=7, help="handicap step (seconds of late start)")
    ap.add_argument("--fair", action="store_true", help="the fair-play figures of issue 26 (then stop)")
    args = ap.parse_args()
    root = pathlib.Path(tempfile.mkdtemp(prefix="bench-league-"))
    try:
        if args.fair:
            fair_figures(root, args)
            return 0
        if not args.skip_throughput:
            throughput_figures(root, args)
        if args.quality_rounds <= 0:
            return 0
        print(f"== rating quality: 16 entrants of known order ({args.quality_late:g} s handicap steps), "
              f"{args.quality_rounds} {args.quality_format} rounds ({args.quality_seconds:g} s matches, demo_room)")
        curve, bt_tau = quality(root, args.quality_rounds, 2, args.quality_format, args.quality_seconds,
                                args.quality_late)
        first = next((n for n, tau in curve if tau >= 0.9), None)
        stays = next((n for i, (n, _) in enumerate(curve) if all(t >= 0.9 for _, t in curve[i:])), None)
        last_quarter = curve[len(curve) - max(1, len(curve) // 4):]
        print("tau after  " + "  ".join(f"{n}:{tau:.2f}" for n, tau in curve))
        held = all(t >= 0.9 for _, t in last_quarter)
        print(f"tau >= 0.9 first after {first} matches, for good after {stays} matches; held over the last "
              f"quarter (after {last_quarter[0][0]} to {last_quarter[-1][0]} matches): {'yes' if held else 'no'}")
        print(f"season end: openskill (in match order) tau {curve[-1][1]:.2f}, order-free Bradley-Terry tau {bt_tau:.2f}")
    finally:
        shutil.rmtree(root, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The league's figures (issue 15): throughput and scaling, rating quality, league overhead.

    .venv/bin/python bench/bench_league.py [--matches 16] [--skip-ray] [--skip-throughput] [--quality-rounds 30] [--quality-format swiss]

1. **Throughput.** ``--matches`` league matches of 5 simulated minutes, 8 robots (two teams of
   four, frontier against explorer and the other reference teams) on ``office``, played by a
   real league (SQLite store, ratings) with one local worker, then two local workers, then on a
   local Ray cluster of two nodes (two raylets of one CPU each, as ``ray start --head`` and a
   second ``ray start`` make). Printed: matches per hour per core, the speed-up over one
   worker and the scaling efficiency (speed-up ÷ workers), and whether every match gave the
   same result (digest of its event log) everywhere. Then, on paper: what a 500-team
   scrimmage season needs.
2. **Overhead.** Per match, the league's own time (building specs, scheduling, storing,
   rating) against the match's time, from the one-worker run.
3. **Rating quality.** 16 entrants of known strength order (``ref-00`` .. ``ref-15``: the
   frontier team with handicap 0..15), ranked rounds (8 two-team matches each, short matches on
   demo_room): random scrimmage pairs, or with ``--quality-format swiss`` neighbours in the
   standing; after each round Kendall's τ between the leaderboard and the true order. Printed:
   the matches after which τ first reaches 0.9 and after which it stays there.
"""
from __future__ import annotations

import argparse
import pathlib
import shutil
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from robo_comp.league import season  # noqa: E402
from robo_comp.league.ratings import kendall_tau  # noqa: E402
from robo_comp.league.runner import LocalRunner, RayRunner  # noqa: E402
from robo_comp.league.store import LeagueStore  # noqa: E402

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
        digests = {m.id: m.result["digest"] for m in store.matches() if m.result}
    fig["schedule_seconds"] = sched
    fig["digests"] = digests
    return fig


def quality(root: pathlib.Path, rounds: int, workers: int, fmt: str = "scrimmage") -> list[tuple[int, float]]:
    """τ of the leaderboard against the true order after each round of 16 entrants: scrimmage
    rounds, or (``fmt="swiss"``) one scrimmage round and then rounds of the league's own Swiss
    format (``league run --format swiss --rounds 1``: neighbours in the standing who have not
    met; rematches once no pairing avoids them)."""
    curve = []
    with LeagueStore(root / f"quality-{fmt}", create=True) as store:
        store.configure(**SHORT)
        subs = season.submit_reference(store, 16)
        truth = [s.team for s in subs]  # ref-00 (no handicap) is the strongest
        runner = LocalRunner(workers)
        played = 0
        for i in range(rounds):
            chosen = "swiss" if fmt == "swiss" and i > 0 else "scrimmage"
            fig = season.run_format(store, runner, chosen, rounds=1, stream=open("/dev/null", "w"))
            played += int(fig["matches"])
            curve.append((played, kendall_tau(season.standing(store), truth)))
    return curve


def throughput_figures(root: pathlib.Path, args: argparse.Namespace) -> None:
    """Throughput on 1 and 2 local workers (and Ray), the season on paper, and the overhead."""
    print(f"== throughput: {args.matches} matches of 300 s, 2 teams x 4 robots, office")
    one = throughput(root, LocalRunner(1), args.matches, "one")
    rate1 = 3600 * one["matches"] / one["wall_seconds"]
    print(f"1 worker : {one['wall_seconds']:.1f} s, {rate1:.0f} matches/hour/core "
          f"({one['match_seconds'] / one['matches']:.2f} s a match)")
    two = throughput(root, LocalRunner(2), args.matches, "two")
    rate2 = 3600 * two["matches"] / two["wall_seconds"]
    print(f"2 workers: {two['wall_seconds']:.1f} s, {rate2:.0f} matches/hour, speed-up {rate2 / rate1:.2f}x, "
          f"efficiency {rate2 / rate1 / 2:.0%}; same results: {two['digests'] == one['digests']}")
    if not args.skip_ray:
        from ray.cluster_utils import Cluster

        cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False})
        cluster.add_node(num_cpus=1)
        cluster.wait_for_nodes()
        runner = RayRunner(cluster.address)
        try:
            ray_fig = throughput(root, runner, args.matches, "ray")
        finally:
            runner.close()
            cluster.shutdown()
        rate_r = 3600 * ray_fig["matches"] / ray_fig["wall_seconds"]
        print(f"Ray, 2 nodes x 1 CPU: {ray_fig['wall_seconds']:.1f} s, {rate_r:.0f} matches/hour, speed-up "
              f"{rate_r / rate1:.2f}x, efficiency {rate_r / rate1 / 2:.0%}; same results: "
              f"{ray_fig['digests'] == one['digests']}")
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
    ap.add_argument("--skip-throughput", action="store_true", help="only the rating-quality run")
    ap.add_argument("--quality-rounds", type=int, default=30, help="rounds of the rating-quality run")
    ap.add_argument("--quality-format", choices=("scrimmage", "swiss"), default="scrimmage",
                    help="random pairs every round, or neighbours in the standing after a first random round")
    args = ap.parse_args()
    root = pathlib.Path(tempfile.mkdtemp(prefix="bench-league-"))
    try:
        if not args.skip_throughput:
            throughput_figures(root, args)
        print(f"== rating quality: 16 entrants of known order, {args.quality_rounds} {args.quality_format} rounds "
              "(60 s matches, demo_room)")
        curve = quality(root, args.quality_rounds, 2, args.quality_format)
        first = next((n for n, tau in curve if tau >= 0.9), None)
        stays = next((n for i, (n, _) in enumerate(curve) if all(t >= 0.9 for _, t in curve[i:])), None)
        print("tau after  " + "  ".join(f"{n}:{tau:.2f}" for n, tau in curve))
        print(f"tau >= 0.9 first after {first} matches, for good after {stays} matches")
    finally:
        shutil.rmtree(root, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

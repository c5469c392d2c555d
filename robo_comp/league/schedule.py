"""Who plays whom: the league's formats, as pure functions of teams, standings and a seed.

* **scrimmage** — continuous ranked play: rounds in which every team (its newest version)
  plays once, in random groups of ``size``;
* **round robin** — every pair of teams meets once (the circle method: ``n − 1`` rounds of
  ``n / 2`` matches; one bye per round with an odd count); for groups larger than two, every
  group of ``size`` teams;
* **Swiss** — each round pairs teams of neighbouring standing that have not met yet (a
  rematch only when no pairing avoids one), two teams that both owe the same start side only
  when no other pairing avoids a rematch, the bye going round;
* **double elimination** — two-team matches seeded by rating; a team is out after its second
  loss; the winners' and the losers' brackets are the teams with no loss and with one loss,
  paired best seed against worst seed; the grand final is played again when the finalist
  from the losers' bracket wins it (a "bracket reset").
"""
from __future__ import annotations

import itertools
import random
from collections import Counter
from collections.abc import Iterable, Mapping
from typing import Any

#: The formats ``robo-comp league run --format`` knows.
FORMATS = ("scrimmage", "round-robin", "swiss", "double-elimination")


def scrimmage(teams: list[str], rounds: int, size: int, rng: random.Random) -> list[list[list[str]]]:
    """``rounds`` rounds of random groups of ``size`` teams (the teams left over when the count
    does not divide sit the round out, a different few each round)."""
    out = []
    for _ in range(rounds):
        order = list(teams)
        rng.shuffle(order)
        out.append([order[k:k + size] for k in range(0, len(order) - size + 1, size)])
    return out


def round_robin(teams: list[str], size: int = 2) -> list[list[list[str]]]:
    """Every pair meets once, in rounds where nobody plays twice (circle method); groups of more
    than two: every combination, one round."""
    if size != 2:
        return [[list(c) for c in itertools.combinations(teams, size)]]
    ring: list[str | None] = list(teams) + ([None] if len(teams) % 2 else [])
    n = len(ring)
    rounds = []
    for _ in range(n - 1):
        pairs = [[ring[i], ring[n - 1 - i]] for i in range(n // 2)]
        rounds.append([[a, b] for a, b in pairs if a is not None and b is not None])
        ring = [ring[0], ring[-1], *ring[1:-1]]
    return rounds


def swiss_round(standing: list[str], played: Iterable[frozenset[str]],
                byes: Iterable[str] = (), lean: Mapping[str, int] | None = None) -> list[list[str]]:
    """Pairs for one Swiss round: down the standing (best first), each team meets the nearest
    one it has not met yet, searching further down (backtracking) when a greedy pairing would
    force a rematch later. Only when no pairing avoids a rematch, each team meets the nearest
    one it has met the fewest times (``played`` lists every earlier meeting, repeats too), so
    the pairs still change from round to round. With an odd count, the lowest team that has not
    had a bye (``byes``) sits the round out.

    ``lean`` (team → matches it started on the first side minus those on the second, so far)
    keeps the sides even over a season: two teams that lean the same way are not paired
    where another pairing without a rematch exists (one of them would have to take its
    over-played side again), so that every team's sides stay at most one apart."""
    times = Counter(played)
    met = set(times)
    free = list(standing)
    side = dict(lean or {})
    outs: list[str | None] = [None]
    if len(free) % 2:
        had = set(byes)
        waiting: list[str | None] = [t for t in reversed(free) if t not in had] or [free[-1]]
        # the lowest team without a bye sits out; the next few only where that keeps sides even
        outs = waiting[:4] if side else waiting[:1]

    def clash(a: str, b: str) -> bool:
        return side.get(a, 0) * side.get(b, 0) > 0

    def search(rest: list[str], clashes: int, budget: list[int]) -> list[list[str]] | None:
        """A pairing of ``rest`` without a rematch and with at most ``clashes`` pairs of teams
        leaning the same way (None: none, or the search ran out of steps)."""
        if not rest:
            return []
        a, others = rest[0], rest[1:]
        for i, b in enumerate(others):
            if frozenset((a, b)) in met:
                continue
            c = clash(a, b)
            if c and clashes == 0:
                continue
            budget[0] -= 1
            if budget[0] < 0:
                return None
            tail = search(others[:i] + others[i + 1:], clashes - c, budget)
            if tail is not None:
                return [[a, b], *tail]
        return None

    # fewest pairs that lean the same way first (none where possible), then any pairing without a
    # rematch; a search runs at most 20,000 steps: a league of hundreds stays fast, past it greedy
    for clashes in ([0, 1, 2, len(free)] if side else [len(free)]):
        for out in outs:
            rest = [t for t in free if t != out]
            found = search(rest, clashes, [20_000])
            if found is not None:
                return found
    if outs[0] is not None:
        free.remove(outs[0])
    pairs = []
    while len(free) > 1:  # no pairing avoids a rematch (or the search ran out): fewest meetings
        a = free.pop(0)
        k = min(range(len(free)), key=lambda i: (times[frozenset((a, free[i]))], clash(a, free[i]), i))
        pairs.append([a, free.pop(k)])
    return pairs


def side_lean(matches: Iterable[list[str]]) -> dict[str, int]:
    """Team → matches it played on the first side minus those on the second (two-team
    matches, each given in side order): what :func:`swiss_round` keeps even."""
    lean: dict[str, int] = {}
    for teams in matches:
        if len(teams) == 2:
            a, b = teams
            lean[a] = lean.get(a, 0) + 1
            lean[b] = lean.get(b, 0) - 1
    return lean


def balance(groups: list[list[str]], scenarios: int, *, prior: dict[str, list[int]] | None = None,
            prior_sides: dict[str, list[int]] | None = None,
            prior_use: list[int] | None = None, scenario: int | None = None) -> list[tuple[list[str], int]]:
    """Give every group (a match) a scenario (0 .. ``scenarios`` − 1) and an order of its teams
    (the order is the start side: the first team takes the scenario's first start zone), so
    that every team plays every scenario, and every side, as evenly as the numbers allow, and
    the scenarios are used evenly overall. ``prior``/``prior_sides``/``prior_use`` are the
    counts of matches already in the league (team → per scenario, team → per side, per
    scenario), so a format scheduled round by round (Swiss) balances across its rounds.

    Greedy first (each match takes the scenario its teams have played least), then a local
    search that moves one match to another scenario, swaps the scenarios of two matches or
    turns a match's sides round, while the sum of squared counts falls (for fixed totals that
    sum is smallest when the counts are as even as they can be). Deterministic.

    ``scenario`` puts every match on that scenario (a Swiss round: one scenario a round, in
    turn, gives every team the same scenarios whoever it is paired with) and balances sides only."""
    S = max(1, int(scenarios))
    teams = sorted({t for g in groups for t in g} | set(prior or {}) | set(prior_sides or {}))
    width = max([len(g) for g in groups] + [max((len(v) for v in (prior_sides or {}).values()), default=0), 2])
    c = {t: list((prior or {}).get(t, [0] * S))[:S] + [0] * max(0, S - len((prior or {}).get(t, []))) for t in teams}
    d = {t: list((prior_sides or {}).get(t, []))[:width] + [0] * max(0, width - len((prior_sides or {}).get(t, [])))
         for t in teams}
    use = list(prior_use or [0] * S)[:S] + [0] * max(0, S - len(prior_use or []))
    plan: list[list[Any]] = []  # [teams in side order, scenario]
    for g in groups:  # greedy: the scenario these teams played least, then the least used; sides by need
        k = scenario % S if scenario is not None else min(range(S), key=lambda s: (sum(c[t][s] for t in g), use[s], s))
        order = min((list(p) for p in itertools.permutations(g)) if len(g) <= 4 else [list(g)],
                    key=lambda p: (sum(d[t][i] for i, t in enumerate(p)), p != list(g)))
        for i, t in enumerate(order):
            c[t][k] += 1
            d[t][i] += 1
        use[k] += 1
        plan.append([order, k])

    def move(j: int, k: int) -> int:
        """Change of the squared sums if match j moved to scenario k."""
        g, s0 = plan[j]
        if k == s0:
            return 0
        delta = sum(2 * (c[t][k] - c[t][s0]) + 2 for t in g)
        return delta * 4 + 2 * (use[k] - use[s0]) + 2  # team balance first, overall use second

    def apply(j: int, k: int) -> None:
        g, s0 = plan[j]
        for t in g:
            c[t][s0] -= 1
            c[t][k] += 1
        use[s0] -= 1
        use[k] += 1
        plan[j][1] = k

    improved = True
    while improved:
        improved = False
        for j in range(len(plan)):
            best = min(range(S), key=lambda k: (move(j, k), k))
            if scenario is None and move(j, best) < 0:
                apply(j, best)
                improved = True
            g = plan[j][0]
            if len(g) == 2:
                a, b = g
                turn = 2 * (d[a][1] - d[a][0]) + 2 + 2 * (d[b][0] - d[b][1]) + 2
                if turn < 0:
                    d[a][0] -= 1
                    d[a][1] += 1
                    d[b][1] -= 1
                    d[b][0] += 1
                    plan[j][0] = [b, a]
                    improved = True
        if not improved and S > 1 and scenario is None:  # stuck: swap the scenarios of two matches
            for i in range(len(plan)):
                s_i = plan[i][1]
                wanted = {k for t in plan[i][0] for k in range(S) if c[t][k] < c[t][s_i] - 1}
                if not wanted:
                    continue  # only a match with a team over-served on its scenario can gain
                for j in range(len(plan)):
                    si, sj = plan[i][1], plan[j][1]
                    if sj not in wanted or si == sj:
                        continue
                    step: dict[tuple[str, int], int] = {}
                    for t in plan[i][0]:
                        step[(t, si)] = step.get((t, si), 0) - 1
                        step[(t, sj)] = step.get((t, sj), 0) + 1
                    for t in plan[j][0]:
                        step[(t, sj)] = step.get((t, sj), 0) - 1
                        step[(t, si)] = step.get((t, si), 0) + 1
                    if sum(2 * c[t][k] * x + x * x for (t, k), x in step.items() if x) < 0:
                        apply(i, sj)
                        apply(j, si)
                        improved = True
    _even_sides(plan, d)
    return [(list(g), int(k)) for g, k in plan]


def _even_sides(plan: list[list[Any]], d: dict[str, list[int]]) -> None:
    """Two-team matches: turn round whole chains of matches (first side → second side) from a
    team that starts first too often to one that starts second too often, until no team's
    sides differ by more than one (an Euler orientation: always possible)."""
    while True:
        over = sorted(t for t, v in d.items() if len(v) >= 2 and v[0] - v[1] >= 2)
        if not over:
            return
        start = over[0]
        out: dict[str, list[int]] = {}
        for j, (g, _) in enumerate(plan):
            if len(g) == 2:
                out.setdefault(g[0], []).append(j)
        seen, queue, back = {start}, [start], {}
        end = None
        while queue and end is None:
            t = queue.pop(0)
            for j in out.get(t, []):
                u = plan[j][0][1]
                if u in seen:
                    continue
                seen.add(u)
                back[u] = j
                if d[u][1] - d[u][0] >= 1 and u != start:
                    end = u
                    break
                queue.append(u)
        if end is None:
            return  # nothing reachable to even out
        u = end
        while u != start:
            j = back[u]
            a, b = plan[j][0]
            plan[j][0] = [b, a]
            d[a][0] -= 1
            d[a][1] += 1
            d[b][1] -= 1
            d[b][0] += 1
            u = a


def elimination_round(seeds: list[str], losses: dict[str, int]) -> list[list[str]]:
    """Pairs for the next double-elimination round. ``seeds`` is the seeding (best first),
    ``losses`` the losses so far. Empty when a champion is known (:func:`champion`)."""
    alive = [t for t in seeds if losses.get(t, 0) < 2]
    if len(alive) < 2:
        return []
    pairs = []
    for bracket in (0, 1):
        group = [t for t in alive if losses.get(t, 0) == bracket]
        if len(alive) == 2 and len(group) < 2:
            continue  # the grand final is played below
        while len(group) > 1:
            pairs.append([group.pop(0), group.pop(-1)])  # best seed against worst seed
    if not pairs and len(alive) == 2:
        pairs.append(alive)  # grand final (or its reset)
    return pairs


def champion(seeds: list[str], losses: dict[str, int]) -> str | None:
    """The double-elimination winner, once only one team has fewer than two losses."""
    alive = [t for t in seeds if losses.get(t, 0) < 2]
    return alive[0] if len(alive) == 1 else None


def longest_first(specs: list[dict[str, Any]],
                  played: Iterable[tuple[list[str], str, dict[str, Any]]]) -> list[dict[str, Any]]:
    """Match specs in the order that ends a run on several workers soonest: the longest expected
    first, so that the short ones fill the end while the last long one plays (each worker takes
    the next spec as it frees up). A match is expected to cost what its teams' earlier matches on
    the same scenario cost per simulated second (their ``cpu_seconds``: the same on a loaded
    machine; ``wall_seconds`` for results without it), shared among their teams, times its
    length; a team with no such match counts the mean of those that have one. ``played``: the
    earlier matches as ``(teams, scenario, result)``. Without any history, or for equal
    expectations, the order stays as given."""
    rates: dict[tuple[str, str], list[float]] = {}
    for teams, scenario, result in played:
        spent, sim = result.get("cpu_seconds") or result.get("wall_seconds"), result.get("sim_seconds")
        if not spent or not sim or not teams:
            continue
        for team in teams:
            rates.setdefault((team, scenario), []).append(float(spent) / float(sim) / len(teams))
    if not rates:
        return list(specs)
    mean = {k: sum(v) / len(v) for k, v in rates.items()}
    overall = sum(mean.values()) / len(mean)

    def expected(spec: dict[str, Any]) -> float:
        teams = [e["team"] for e in spec["entrants"]]
        return float(spec.get("seconds", 300)) * sum(mean.get((t, spec["scenario"]), overall) for t in teams)

    return sorted(specs, key=expected, reverse=True)  # (a stable sort: equal ones keep their order)


__all__ = ["FORMATS", "balance", "champion", "elimination_round", "longest_first", "round_robin", "scrimmage",
           "side_lean", "swiss_round"]

"""Who plays whom: the league's formats, as pure functions of teams, standings and a seed.

* **scrimmage** — continuous ranked play: rounds in which every team (its newest version)
  plays once, in random groups of ``size``;
* **round robin** — every pair of teams meets once (the circle method: ``n − 1`` rounds of
  ``n / 2`` matches; one bye per round with an odd count); for groups larger than two, every
  group of ``size`` teams;
* **Swiss** — each round pairs teams of neighbouring standing that have not met yet (a
  rematch only when no pairing avoids one), the bye going round;
* **double elimination** — two-team matches seeded by rating; a team is out after its second
  loss; the winners' and the losers' brackets are the teams with no loss and with one loss,
  paired best seed against worst seed; the grand final is played again when the finalist
  from the losers' bracket wins it (a "bracket reset").
"""
from __future__ import annotations

import itertools
import random
from collections import Counter
from collections.abc import Iterable

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
                byes: Iterable[str] = ()) -> list[list[str]]:
    """Pairs for one Swiss round: down the standing (best first), each team meets the nearest
    one it has not met yet, searching further down (backtracking) when a greedy pairing would
    force a rematch later. Only when no pairing avoids a rematch, each team meets the nearest
    one it has met the fewest times (``played`` lists every earlier meeting, repeats too), so
    the pairs still change from round to round. With an odd count, the lowest team that has not
    had a bye (``byes``) sits the round out."""
    times = Counter(played)
    met = set(times)
    free = list(standing)
    if len(free) % 2:
        had = set(byes)
        out = next((t for t in reversed(free) if t not in had), free[-1])
        free.remove(out)
    budget = [20_000]  # search steps: a league of hundreds stays fast; past it, greedy

    def search(rest: list[str]) -> list[list[str]] | None:
        if not rest:
            return []
        a, others = rest[0], rest[1:]
        for i, b in enumerate(others):
            if frozenset((a, b)) in met:
                continue
            budget[0] -= 1
            if budget[0] < 0:
                return None
            tail = search(others[:i] + others[i + 1:])
            if tail is not None:
                return [[a, b], *tail]
        return None

    found = search(free)
    if found is not None:
        return found
    pairs = []
    while len(free) > 1:  # no pairing avoids a rematch (or the search ran out): fewest meetings
        a = free.pop(0)
        k = min(range(len(free)), key=lambda i: (times[frozenset((a, free[i]))], i))
        pairs.append([a, free.pop(k)])
    return pairs


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


__all__ = ["FORMATS", "champion", "elimination_round", "round_robin", "scrimmage", "swiss_round"]

"""Ratings for N-team matches: openskill's Plackett–Luce model, leaderboard by μ − 3σ.

A match ranks its teams by score (equal scores share a rank); openskill moves each team's
(μ, σ) from that ranking. The leaderboard orders teams by the conservative estimate μ − 3σ,
so a team that played little ranks low until its σ shrinks. Unranked (test) matches never
reach :func:`rate`.
"""
from __future__ import annotations

from functools import lru_cache
from typing import Any


@lru_cache(maxsize=1)
def model() -> Any:
    """The rating model (openskill's Plackett–Luce with its default μ = 25, σ = 25/3)."""
    from openskill.models import PlackettLuce

    return PlackettLuce()


def initial() -> tuple[float, float]:
    """A new team's (μ, σ)."""
    r = model().rating()
    return float(r.mu), float(r.sigma)


def rate(current: dict[str, tuple[float, float]], ranks: dict[str, int]) -> dict[str, tuple[float, float]]:
    """The teams' new (μ, σ) after a match that ranked them ``ranks`` (1 = best)."""
    m = model()
    teams = list(ranks)
    players = [[m.rating(mu=current[t][0], sigma=current[t][1])] for t in teams]
    new = m.rate(players, ranks=[ranks[t] for t in teams])
    return {t: (float(p[0].mu), float(p[0].sigma)) for t, p in zip(teams, new)}


#: A rating is provisional (marked ``?`` on the table, the report and the console) until its
#: σ falls below this: about 20 two-team matches (σ starts at 8.33); the 16-entrant reference
#: field's order reached Kendall's τ 0.9 after 19 matches an entrant and held it
#: (docs/performance.md, "League fair play").
SURE_SIGMA = 5.0


def provisional(sigma: float) -> bool:
    """True while a rating's σ says too little is known to trust its rank."""
    return sigma >= SURE_SIGMA


def ordinal(mu: float, sigma: float) -> float:
    """The leaderboard's value: μ − 3σ."""
    return mu - 3.0 * sigma


def bradley_terry(matches: list[dict[str, int]], *, iterations: int = 500) -> dict[str, tuple[float, float]]:
    """An order-free re-rating of a season: the Bradley–Terry strengths that best explain every
    pairwise result at once (``matches``: each a ranks dict, team → 1 for the best; within a
    match every pair counts, a tie as half a win each), whatever order the matches were played
    in. Returns team → (log-strength, its standard error); one virtual tie of every team against
    an average opponent keeps a team that won (or lost) everything finite. Hunter's MM
    algorithm (2004)."""
    import math

    teams = sorted({t for m in matches for t in m})
    if not teams:
        return {}
    wins = {t: 0.5 for t in teams}  # the virtual tie
    meet: dict[tuple[str, str], float] = {}
    for m in matches:
        ts = sorted(m)
        for i, a in enumerate(ts):
            for b in ts[i + 1:]:
                meet[(a, b)] = meet.get((a, b), 0.0) + 1.0
                if m[a] < m[b]:
                    wins[a] += 1.0
                elif m[b] < m[a]:
                    wins[b] += 1.0
                else:
                    wins[a] += 0.5
                    wins[b] += 0.5
    p = {t: 1.0 for t in teams}
    for _ in range(iterations):
        new = {}
        for t in teams:
            denom = 1.0 / (p[t] + 1.0)  # the virtual opponent of strength 1
            for (a, b), n in meet.items():
                if t in (a, b):
                    denom += n / (p[a] + p[b])
            new[t] = wins[t] / denom
        scale = math.exp(sum(math.log(v) for v in new.values()) / len(new))
        p = {t: v / scale for t, v in new.items()}
    out = {}
    for t in teams:
        info = p[t] / (p[t] + 1.0) ** 2
        for (a, b), n in meet.items():
            if t in (a, b):
                info += n * p[a] * p[b] / (p[a] + p[b]) ** 2
        out[t] = (math.log(p[t]), 1.0 / math.sqrt(info))
    return out


def kendall_tau(a: list[str], b: list[str]) -> float:
    """Kendall's τ between two orderings of the same items (1: the same order, −1: reversed)."""
    pos = {x: i for i, x in enumerate(b)}
    n = len(a)
    if n < 2:
        return 1.0
    concordant = discordant = 0
    for i in range(n):
        for j in range(i + 1, n):
            s = pos[a[i]] - pos[a[j]]
            if s < 0:
                concordant += 1
            elif s > 0:
                discordant += 1
    return (concordant - discordant) / (n * (n - 1) / 2)


__all__ = ["SURE_SIGMA", "bradley_terry", "initial", "kendall_tau", "model", "ordinal", "provisional", "rate"]

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
#: σ falls below this: 2σ then spans about one rank step of the leaderboard's μ − 3σ.
SURE_SIGMA = 2.5


def provisional(sigma: float) -> bool:
    """True while a rating's σ says too little is known to trust its rank."""
    return sigma >= SURE_SIGMA


def ordinal(mu: float, sigma: float) -> float:
    """The leaderboard's value: μ − 3σ."""
    return mu - 3.0 * sigma


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


__all__ = ["SURE_SIGMA", "initial", "kendall_tau", "model", "ordinal", "provisional", "rate"]

"""A/B comparison: is version B of a team better than version A?

Both versions play the same matches (the league's engine, :func:`robo_comp.league.engine.play_match`):
against the same opponents, on the same scenarios and seeds, from the same side, under the
same team name, so the only difference between a pair of matches is the code. The answer is
the mean of B's score minus A's score over the pairs, with a 95 % confidence interval from the
paired differences (Student's t), and the pairs where the two versions differ most, with the
commands that replay them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from robo_comp.errors import FieldError

#: The name both versions play under (the opponents keep theirs).
CANDIDATE = "candidate"
#: Student's t, two-sided 95 %, for 1..30 degrees of freedom.
_T975 = (12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160, 2.145,
         2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048,
         2.045, 2.042)


def t975(df: int) -> float:
    """Student's t quantile 0.975 with ``df`` degrees of freedom (a series past 30: within 0.001)."""
    if df < 1:
        return math.inf
    if df <= len(_T975):
        return _T975[df - 1]
    z = 1.959964
    return z + (z ** 3 + z) / (4 * df) + (5 * z ** 5 + 16 * z ** 3 + 3 * z) / (96 * df ** 2)


@dataclass
class Pair:
    """One setup played by both versions: ``key`` (opponent, scenario, seed, side), each
    version's score and its match's log."""

    opponent: str
    scenario: str
    seed: int
    side: int
    score: dict[str, float] = field(default_factory=dict)
    log: dict[str, str] = field(default_factory=dict)

    @property
    def diff(self) -> float:
        """B's score minus A's."""
        return self.score["B"] - self.score["A"]


@dataclass
class Comparison:
    """What :func:`compare` found: the pairs, the mean difference and its 95 % interval."""

    pairs: list[Pair]
    mean: float
    low: float
    high: float
    failed: list[str]

    def verdict(self) -> str:
        """One sentence: which is better, or that the matches cannot tell."""
        if self.low > 0:
            return "B is better than A (the whole interval is above 0)"
        if self.high < 0:
            return "B is worse than A (the whole interval is below 0)"
        return "the matches cannot tell A and B apart (the interval holds 0): play more seeds"


def paired_interval(diffs: list[float]) -> tuple[float, float, float]:
    """Mean of the paired differences and its 95 % confidence interval (Student's t)."""
    n = len(diffs)
    if n == 0:
        raise FieldError("no pair of matches was played: nothing to compare")
    mean = sum(diffs) / n
    if n == 1:
        return mean, -math.inf, math.inf
    sd = math.sqrt(sum((d - mean) ** 2 for d in diffs) / (n - 1))
    half = t975(n - 1) * sd / math.sqrt(n)
    return mean, mean - half, mean + half


def plan(a: dict[str, str], b: dict[str, str], opponents: dict[str, dict[str, str]], scenarios: list[str],
         seeds: list[int], *, robots: int, seconds: float, out: Path) -> tuple[list[Pair], list[dict[str, Any]]]:
    """The pairs and the match specs: every opponent × scenario × seed, each version once; the
    candidate starts in the first slot on even seeds, the second on odd ones."""
    pairs: list[Pair] = []
    specs: list[dict[str, Any]] = []
    for opponent, files in opponents.items():
        for scenario in scenarios:
            for seed in seeds:
                side = seed % 2
                k = len(pairs)
                pair = Pair(opponent, scenario, seed, side)
                pairs.append(pair)
                for version, code in (("A", a), ("B", b)):
                    cand = {"team": CANDIDATE, "version": version, "files": code}
                    other = {"team": opponent, "version": "opponent", "files": files}
                    log = out / f"pair-{k:03d}" / f"{version}.log"
                    log.parent.mkdir(parents=True, exist_ok=True)
                    pair.log[version] = str(log)
                    specs.append({"id": f"{k}:{version}", "scenario": scenario, "seed": seed, "seconds": seconds,
                                  "robots": robots, "entrants": [cand, other] if side == 0 else [other, cand],
                                  "log": str(log)})
    return pairs, specs


def compare(a: dict[str, str], b: dict[str, str], opponents: dict[str, dict[str, str]], scenarios: list[str],
            seeds: list[int], *, robots: int, seconds: float, out: Path, runner: Any) -> Comparison:
    """Play both versions against every opponent on every scenario and seed (on ``runner``, a
    :class:`robo_comp.league.runner.LocalRunner` or ``RayRunner``) and compare them."""
    if CANDIDATE in opponents:
        raise FieldError(f"an opponent cannot be called {CANDIDATE!r} (the name both versions play under)")
    pairs, specs = plan(a, b, opponents, scenarios, seeds, robots=robots, seconds=seconds, out=out)
    failed: list[str] = []

    def on_result(spec: dict[str, Any], result: dict[str, Any]) -> None:
        k, version = str(spec["id"]).split(":")
        pairs[int(k)].score[version] = float(result["scores"][CANDIDATE])

    def on_error(spec: dict[str, Any], message: str) -> None:
        failed.append(f"match {spec['id']}: {message.strip().splitlines()[-1][:200]}")

    runner.run(specs, on_result, on_error)
    done = [p for p in pairs if "A" in p.score and "B" in p.score]
    mean, low, high = paired_interval([p.diff for p in done])
    return Comparison(done, mean, low, high, failed)


def report(c: Comparison, shown: int = 3) -> str:
    """The comparison as the lines ``robo-comp league compare`` prints."""
    n = len(c.pairs)
    mean_a = sum(p.score["A"] for p in c.pairs) / n
    mean_b = sum(p.score["B"] for p in c.pairs) / n
    lines = [f"{n} pairs of matches (same opponent, scenario, seed and side; A and B each played once)",
             f"mean score: A {mean_a:.2f}, B {mean_b:.2f}",
             f"B - A: {c.mean:+.2f} points a match, 95 % confidence interval [{c.low:+.2f}, {c.high:+.2f}] "
             "(paired by seed)", c.verdict()]
    if c.failed:
        lines.append(f"{len(c.failed)} match(es) failed and are left out: " + "; ".join(c.failed[:3]))
    ranked = sorted(c.pairs, key=lambda p: (-abs(p.diff), p.opponent, p.scenario, p.seed))[:shown]
    if ranked:
        lines.append("where they differ most (watch them: robo-comp web --replay LOG):")
    for p in ranked:
        lines.append(f"  vs {p.opponent} on {p.scenario}, seed {p.seed}: A {p.score['A']:g}, B {p.score['B']:g} "
                     f"({p.diff:+g})")
        lines.append(f"    robo-comp web --replay {p.log['A']}")
        lines.append(f"    robo-comp web --replay {p.log['B']}")
    return "\n".join(lines)


__all__ = ["CANDIDATE", "Comparison", "Pair", "compare", "paired_interval", "plan", "report", "t975"]

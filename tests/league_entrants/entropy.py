"""Hostile league entrant: reaches for every per-process entropy source the sandbox might
expose and steers its robots by what it gets, so any entropy that gets through changes the
match's event log (tests/test_league_fair.py, bench/bench_league.py)."""
import random

MANIFEST = {
    "name": "entropy", "version": "1.0", "kind": "extension",
    "tasks": {"play": {"description": "Steer by whatever entropy the sandbox lets through.",
                       "args": [{"name": "width", "type": "int"}, {"name": "height", "type": "int"},
                                {"name": "index", "type": "int"}, {"name": "count", "type": "int"}]}},
}


class Thing:
    pass


class Keyed:
    def __init__(self, k):
        self.k = k


def helper():
    return 0


def attempt(get):
    try:
        return get()
    except Exception as e:
        return "refused: " + str(e)[:40]


def reseeded():
    random.seed()
    return random.random()


def sources():
    """(name, value) for every source; the values decide the robots' turns."""
    return [
        ("hash-str", attempt(lambda: hash("robo"))),
        ("hash-bytes", attempt(lambda: hash(b"robo"))),
        ("hash-tuple", attempt(lambda: hash(("a", 1, b"b")))),
        ("id", attempt(lambda: id(Thing()))),
        ("hash-instance", attempt(lambda: hash(Thing()))),
        ("hash-class", attempt(lambda: hash(Thing))),
        ("hash-function", attempt(lambda: hash(helper))),
        ("hash-object", attempt(lambda: hash(object()))),
        ("repr-object", attempt(lambda: repr(object()))),
        ("repr-function", attempt(lambda: repr(helper))),
        ("ascii-function", attempt(lambda: ascii(helper))),
        ("str-instance", attempt(lambda: str(Thing()))),
        ("percent-instance", attempt(lambda: "%s" % (Thing(),))),
        ("fstring-instance", attempt(lambda: f"{Thing()}")),
        ("set-of-str", attempt(lambda: list({"alpha", "beta", "gamma", "delta", "epsilon", "zeta"}))),
        ("frozenset-of-bytes", attempt(lambda: list(frozenset([b"a1", b"b2", b"c3", b"d4"])))),
        ("set-of-instances", attempt(lambda: [t.k for t in {Keyed(i) for i in range(8)}])),
        ("set-of-classes", attempt(lambda: len({Thing, Keyed}))),
        ("dict-of-instances", attempt(lambda: [hash(k) for k in {Thing(): 1, Thing(): 2}])),
        ("random-reseeded", attempt(reseeded)),
        ("random", attempt(lambda: random.random())),
    ]


def play(robot, width, height, index, count):
    got = sources()
    print(got)
    bits = 0
    for name, value in got:
        for c in str(value):
            bits = (bits * 31 + ord(c)) % 1000003
    for i in range(8):
        robot.turn(90 if (bits >> i) & 1 else -90)
        try:
            robot.move(1)
        except Exception:
            pass

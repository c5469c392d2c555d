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

    def get(self):
        return self.k


def helper():
    return 0


def attempt(get):
    try:
        return get()
    except Exception as e:
        return "refused: " + str(e)[:40]


def gen():
    yield 1


def order(items, make):
    """Where each of ``items`` lands when ``make`` puts them in a set (or a dict's keys): the
    order a set of them is walked in follows their hashes."""
    return [items.index(x) for x in make(items)]


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
        # every way to turn an address-printing object into text, not only repr()
        ("str-function", attempt(lambda: str(helper))),
        ("fstring-function", attempt(lambda: f"{helper}")),
        ("fstring-repr-function", attempt(lambda: f"{helper!r}")),
        ("percent-function", attempt(lambda: "%s" % (helper,))),
        ("percent-repr-lambda", attempt(lambda: "%r" % (lambda: 0,))),
        ("format-function", attempt(lambda: format(helper))),
        ("str-method", attempt(lambda: str(Keyed(1).get))),
        ("fstring-builtin-method", attempt(lambda: f"{[].append}")),
        ("fstring-generator", attempt(lambda: f"{gen()}")),
        ("percent-object", attempt(lambda: "%s" % (object(),))),
        ("fstring-iterator", attempt(lambda: f"{iter([1])} {map(abs, [1])} {zip([1])}")),
        ("str-list-of-functions", attempt(lambda: str([helper, gen, Keyed.get]))),
        ("fstring-dict-of-objects", attempt(lambda: f"{ {1: object()} }")),
        ("error-text", attempt(lambda: [1].index(helper))),
        # the order of sets of objects Python hashes by address
        ("set-of-functions", attempt(lambda: order([lambda i=i: i for i in range(24)], set))),
        ("frozenset-of-functions", attempt(lambda: order([helper, gen, reseeded, sources, order, attempt], frozenset))),
        ("set-of-objects", attempt(lambda: order([object() for i in range(24)], set))),
        ("set-of-generators", attempt(lambda: order([gen() for i in range(24)], set))),
        ("set-of-methods", attempt(lambda: order([Keyed(i).get for i in range(24)], set))),
        ("set-of-builtins", attempt(lambda: order([len, abs, min, max, sum, sorted, any, isinstance, round,
                                                    divmod, chr, ord, pow, hash, repr], set))),
        ("set-of-types", attempt(lambda: order([int, str, float, list, dict, tuple, set, bytes, bool, object,
                                                 ValueError, KeyError, TypeError, range, slice, Thing, Keyed], set))),
        ("set-of-singletons", attempt(lambda: order([None, Ellipsis, NotImplemented, True, 2, 3, 17, 33], set))),
        ("set-of-team-objects", attempt(lambda: order([Thing() for i in range(24)], set))),
        ("dict-keyed-by-functions", attempt(lambda: order([lambda: 0 for i in range(24)],
                                                          lambda fs: set({f: 1 for f in fs})))),
        ("random-reseeded", attempt(reseeded)),
        ("random", attempt(lambda: random.random())),
    ]


def play(robot, width, height, index, count):
    got = sources()
    for item in got:  # a line each: a printed line is cut at 2,000 characters in the log
        print(item)
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

"""Swallow every exception (timeouts, cancels) with except BaseException."""
# expect: run
# match: (wall-clock|CPU time) limit
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    while True:
        try:
            while True:
                pass
        except BaseException:
            pass

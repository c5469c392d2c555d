"""Allocate, swallow MemoryError, allocate again forever."""
# expect: run
# match: (memory limit|wall-clock limit|CPU time limit)
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    hog = []
    while True:
        try:
            hog.append(bytes(50 * 1024 * 1024))
        except BaseException:
            pass

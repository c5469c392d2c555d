"""Grow a list without bound."""
# expect: run
# match: memory limit \(\d+ MiB\) exceeded
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    hog = []
    while True:
        hog.append([0] * 4000000)  # 32 MB a step: the memory limit comes long before the clock

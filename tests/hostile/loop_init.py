"""An infinite loop in init()."""
# expect: upload
# match: (init: .*did not finish within|CPU time limit)
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def init(robot):
    while True:
        pass


def attack(robot):
    return 1

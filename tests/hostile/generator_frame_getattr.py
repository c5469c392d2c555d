"""Generator gi_frame reached with getattr and a computed name."""
# expect: run
# match: "gi_frame" is a restricted attribute
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def gen():
    yield 1


def attack(robot):
    g = gen()
    return getattr(g, 'gi_' + 'frame')

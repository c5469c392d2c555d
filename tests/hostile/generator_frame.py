"""Generator gi_frame walk to the caller's frame."""
# expect: upload
# match: policy: .*`\.gi_frame` reaches into the interpreter's frames
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
    return g.gi_frame.f_back.f_globals

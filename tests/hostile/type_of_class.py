"""Get the real metaclass via type(int) and build a class with a __del__ hook."""
# expect: run
# match: type\(\) of a class .* not available
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}


def hook(self):
    while True:
        pass


def attack(robot):
    meta = type(int)
    evil = meta("Evil", (object,), {"__del__": hook})
    return evil()

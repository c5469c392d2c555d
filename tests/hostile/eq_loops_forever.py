"""An object whose __eq__ never returns."""
# expect: run
# match: (wall-clock|CPU time) limit
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

class Evil:
    def __eq__(self, other):
        while True:
            pass


def attack(robot):
    return Evil() == 1

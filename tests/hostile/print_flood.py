"""print() in an endless loop."""
# expect: run
# match: output limit \(\d+ KiB\) exceeded
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    while True:
        print('spam ' * 20)

"""An argument type the contract does not know."""
# expect: upload
# match: manifest: .*'type' must be one of
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": [{"name": "side", "type": "integer"}]}},
}

def attack(robot, side):
    return side

"""f-string with a conversion on a dunder attribute."""
# expect: upload
# match: policy: .*\(`\.__class__`\) are Python's internals
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return f'{robot.__class__!r:>{10}}'

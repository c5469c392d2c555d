"""async functions (event-loop escape)."""
# expect: upload
# match: policy: .*async functions are not allowed in team code; write a plain `def`
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

async def attack(robot):
    return 1

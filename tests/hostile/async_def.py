"""async functions (event-loop escape)."""
# expect: upload
# match: policy: .*AsyncFunctionDef statements are not allowed
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

async def attack(robot):
    return 1

"""Hide a dunder behind full-width letters (identifiers are NFKC-normalised)."""
# expect: upload
# match: policy: .*\(`\.__class__`\) are Python's internals
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}


def attack(robot):
    return robot.__ｃｌａｓｓ__

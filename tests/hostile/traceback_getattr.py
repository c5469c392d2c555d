"""Reach the traceback through getattr with a computed name."""
# expect: run
# match: "__traceback__" is an invalid attribute name
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    try:
        1 / 0
    except ZeroDivisionError as e:
        tb = getattr(e, '__trace' + 'back__')
        return getattr(tb, 'tb_frame')

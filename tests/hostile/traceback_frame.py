"""Traceback tb_frame / f_back walk from a caught exception."""
# expect: upload
# match: policy: .*\(`\.__traceback__`\) are Python's internals
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
        return e.__traceback__.tb_frame.f_back

"""A class with its own metaclass."""
# expect: upload
# match: policy: .*metaclass
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

class Meta(type):
    pass


class X(metaclass=Meta):
    pass


def attack(robot):
    return 1

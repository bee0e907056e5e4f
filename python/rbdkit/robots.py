"""The robots bundled with rbdkit (iiwa14, HyQ, Atlas: see robots/SOURCES.md
for their source and licence)."""

import os

from ._model import Model

_DIR = os.path.join(os.path.dirname(__file__), "robots_data")
_ALIASES = {"iiwa": "iiwa", "iiwa14": "iiwa", "hyq": "hyq", "atlas": "atlas"}


def names():
    """names of the bundled robots"""
    return sorted({v for v in _ALIASES.values()})


def path(name):
    """the URDF file of a bundled robot"""
    if not isinstance(name, str):
        raise TypeError(f"name: expected a robot name (str), got {type(name).__name__}")
    key = _ALIASES.get(name.lower())
    if key is None:
        raise ValueError(f"name: unknown robot {name!r}; bundled robots are {', '.join(names())}")
    return os.path.join(_DIR, key + ".urdf")


def load(name, floating_base=False):
    """load a bundled robot by name ('iiwa' (or 'iiwa14'), 'hyq', 'atlas')"""
    return Model.from_urdf(path(name), floating_base=floating_base)


def handle(name, floating_base=False, **kw):
    """an rbdkit.Handle of a bundled robot; keywords as rbdkit.Handle
    (algorithms, backend, dtype, threads, output_convention)"""
    from ._handle import Handle
    return Handle(load(name, floating_base=floating_base), **kw)

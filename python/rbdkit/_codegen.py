"""rbdkit.generate: a robot as one readable C++ header of per-robot functions
(`rbdkit generate`; docs/generated-code.md)."""

import os

from . import _core


def generate(model, name, path=None, source=None, runtime_inertias=False):
    """the header text for `model` (an rbdkit.Model) as struct `name` in
    namespace rbdkit_generated, written to `path` when one is given.

    The header holds the model as constants and the entry points
    inverse_dynamics, aba, crba, minv, inverse_dynamics_gradient,
    forward_dynamics_gradient and integrator_gradient, each a
    `template <class S> static` function on raw pointers that instantiates
    rbdkit's own header-only algorithms: compile it with -I on rbdkit's
    include folder (rbdkit.include_dir()), nothing to link, with g++, clang or
    nvcc (inside your kernels). `source` names where the model came from in
    the header's first comment. runtime_inertias: the inertias are an
    argument instead of constants, `const S* pi` (10·nb, Model.inertial_parameters'
    layout) first in every entry point, for identification. ValueError for a
    name that is not a C++ identifier, is a keyword or one of the struct's
    members, and for a model without bodies."""
    from ._model import Model
    if not isinstance(model, Model):
        raise TypeError(f"model: expected an rbdkit.Model, got {type(model).__name__}")
    if not isinstance(name, str):
        raise TypeError(f"name: expected a str, got {type(name).__name__}")
    text = _core.generate_header(model._core, name, source or "", bool(runtime_inertias))
    if path is not None:
        path = os.fspath(path)
        folder = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(folder):
            raise FileNotFoundError(f"path: the folder '{folder}' does not exist")
        with open(path, "w") as f:
            f.write(text)
    return text


def include_dir():
    """the folder to put on the include path of a generated header (rbdkit's header-only algorithms)"""
    here = os.path.dirname(os.path.abspath(__file__))
    for candidate in (os.path.join(here, "include"),  # an installed package
                      os.path.join(here, "..", "..", "include")):  # a source checkout
        if os.path.isfile(os.path.join(candidate, "rbdkit", "algorithms", "rnea.hpp")):
            return os.path.normpath(candidate)
    raise FileNotFoundError("rbdkit's headers were not found next to the package (install rbdkit with pip, or "
                            "use a source checkout's include/ folder)")

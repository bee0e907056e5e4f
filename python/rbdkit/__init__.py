"""rbdkit: rigid-body dynamics and their derivatives for robot trajectory
optimization and learning.

    import rbdkit
    model = rbdkit.robots.load("iiwa")            # or rbdkit.Model.from_urdf(path)
    rbd = rbdkit.RBD(model)
    tau, v, a, f = rbd.inverse_dynamics(q, qd, qdd)

Every RBD method takes one sample (q of shape (nq,)) or a batch with the
batch on axis 0 (q of shape (B, nq)) and returns results to match.
A Handle (rbdkit.Handle(model, algorithms=...)) is built with a chosen set
of algorithms, a precision and a thread count, and runs the same operations
on batched arrays. Conventions: docs/conventions.md. rbdkit.generate(model,
name, path) writes a robot as a C++ header of per-robot functions
(docs/generated-code.md).
"""

from ._model import Model
from ._builder import ModelBuilder
from ._rbd import RBD
from ._handle import Handle, cuda_available
from ._solver import solve_trajectory, TrajectoryResult
from . import robots
from ._codegen import generate, include_dir

__all__ = ["Model", "ModelBuilder", "RBD", "Handle", "cuda_available", "robots", "solve_trajectory", "TrajectoryResult",
           "generate", "include_dir"]
__version__ = "0.1.0"

"""rbdkit: rigid-body dynamics and their derivatives for robot trajectory
optimization and learning.

    import rbdkit
    model = rbdkit.robots.load("iiwa")            # or rbdkit.Model.from_urdf(path)
    rbd = rbdkit.RBD(model)
    tau, v, a, f = rbd.inverse_dynamics(q, qd, qdd)

Every RBD method takes one sample (q of shape (nq,)) or a batch with the
batch on axis 0 (q of shape (B, nq)) and returns results to match.
Conventions: docs/conventions.md.
"""

from ._model import Model
from ._rbd import RBD
from . import robots

__all__ = ["Model", "RBD", "robots"]
__version__ = "0.1.0"

"""Open-loop trajectory optimisation by gradient descent through 50
differentiable rk4 plant steps (rbdkit.torch): the iiwa's joint state is
driven from rest to a target configuration by a torque sequence, optimised
with L-BFGS on the final-state error plus a small effort cost. The gradient PyTorch's autograd returns is checked against the
analytical chain of the steps' [A | B] Jacobians (plant_step_gradient) before
the optimisation starts.

    python3 examples/torch_rollout.py [--iters 100] [--steps 50]
"""

import argparse

import numpy as np
import torch

import rbdkit
import rbdkit.torch

DT = 0.01


def rollout(h, x0, U):
    """the states x_1 .. x_N of the rk4 plant from x0 under torques U (N, nv)"""
    xs, x = [], x0
    for u in U:
        x = h.plant_step(x, u, DT, "rk4")
        xs.append(x)
    return torch.stack(xs)


def loss_of(h, x0, U, target, effort):
    xs = rollout(h, x0, U)
    return ((xs[-1] - target) ** 2).sum() + effort * (U ** 2).sum()


def chain_gradient(h, x0, U, target, effort):
    """∂loss/∂U from the analytical Jacobians: backward through x_{k+1} = f(x_k, u_k) with
    [A_k | B_k] (tangent space, plant_step_gradient), the final error's gradient taken on the
    coordinates and mapped to the tangent space (fixed base: the same)"""
    X = [x0.detach().numpy()]
    for u in U.detach().numpy():
        X.append(h.numpy.plant_step(X[-1], u, DT, "rk4"))
    lam = 2 * (X[-1] - target.numpy())  # ∂loss/∂x_N
    nv = h.nv
    G = np.zeros(U.shape)
    for k in reversed(range(len(U))):
        AB = h.numpy.plant_step_gradient(X[k], U[k].detach().numpy(), DT, "rk4")
        G[k] = AB[:, 2 * nv:].T @ lam + 2 * effort * U[k].detach().numpy()
        lam = AB[:, :2 * nv].T @ lam
    return G


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--iters", type=int, default=100, help="L-BFGS iterations at most")
    p.add_argument("--steps", type=int, default=50)
    o = p.parse_args(argv)
    model = rbdkit.robots.load("iiwa")
    h = rbdkit.torch.Handle(model, threads=1)
    nq, nv = model.nq, model.nv
    x0 = torch.zeros(nq + nv, dtype=torch.float64)
    target = torch.tensor(np.r_[0.3 * np.ones(nq), np.zeros(nv)])
    effort = 1e-7
    # gravity compensation at rest as the first guess
    g = h.numpy.generalized_gravity(np.zeros(nq))
    U = torch.tensor(np.tile(g, (o.steps, 1)), requires_grad=True)
    # the torques as u_k = g + M(q0) w_k: the optimiser's variables w are accelerations, of one scale for
    # light distal joints and heavy proximal ones (the torques' scales differ by orders of magnitude)
    M0 = torch.tensor(h.numpy.crba(np.zeros(nq)))
    g_t = torch.tensor(g)

    loss = loss_of(h, x0, U, target, effort)
    loss.backward()
    G = chain_gradient(h, x0, U, target, effort)
    err = np.max(np.abs(U.grad.numpy() - G)) / np.max(np.abs(G))
    print(f"autograd gradient vs the analytical [A | B] chain: max relative difference {err:.2e}")

    # L-BFGS (strong Wolfe line search) on w
    W = torch.zeros(o.steps, nv, dtype=torch.float64, requires_grad=True)
    torques = lambda W: g_t + W @ M0.T  # noqa: E731
    opt = torch.optim.LBFGS([W], lr=1.0, max_iter=o.iters, history_size=20, line_search_fn="strong_wolfe",
                            tolerance_grad=1e-12, tolerance_change=1e-15)
    first = float(loss.detach())
    evals = [0]

    def closure():
        opt.zero_grad()
        loss = loss_of(h, x0, torques(W), target, effort)
        loss.backward()
        evals[0] += 1
        if evals[0] % 25 == 1:
            print(f"evaluation {evals[0]:4d}  loss {float(loss.detach()):.3e}")
        return loss

    opt.step(closure)
    U = torques(W.detach())
    final = float(loss_of(h, x0, U, target, effort))
    xN = rollout(h, x0, U)[-1]
    print(f"loss {first:.3e} -> {final:.3e}; final joint error {float((xN[:nq] - target[:nq]).abs().max()):.3e} rad")
    return err, first, final


if __name__ == "__main__":
    main()

"""A batch of knot points split across processes with torch.distributed: each
rank evaluates its shard with rbdkit.torch (forward dynamics and the RK4 step
of a floating HyQ), an all-gather puts the shards back together, and rank 0
checks that the result equals the unsharded call.

    python3 examples/torch_distributed.py [--world 2] [--batch 64]
    torchrun --standalone --nproc-per-node 2 examples/torch_distributed.py [--batch 64]

Started plainly, it starts its own processes (torch.multiprocessing, gloo,
on this machine). Under torchrun (RANK and WORLD_SIZE set), on one or several
machines, each process is one rank of torchrun's group and runs the same
`evaluate` (docs/scaling.md).
"""

import argparse
import os
import socket

import numpy as np
import torch
import torch.distributed as dist
import torch.multiprocessing as mp

import rbdkit
import rbdkit.torch


def batch(model, B, seed=0):
    rng = np.random.default_rng(seed)
    q = np.stack([model.random_configuration(rng) for _ in range(B)])
    return q, rng.uniform(-1, 1, (B, model.nv)), rng.uniform(-1, 1, (B, model.nv))


def evaluate(rank, world, B):
    """this rank's shard of the batch, computed here, then all-gathered: (qdd, x⁺) of all B samples"""
    model = rbdkit.robots.load("hyq", floating_base=True)
    h = rbdkit.torch.Handle(model, threads=1)
    q, qd, u = (torch.from_numpy(a) for a in batch(model, B))
    shard = slice(rank * B // world, (rank + 1) * B // world)  # contiguous, equal shards (B % world == 0)
    qdd = h.forward_dynamics(q[shard], qd[shard], u[shard])
    x_next = h.integrator(q[shard], qd[shard], u[shard], 0.01, "rk4")
    out = []
    for local in (qdd, x_next):
        parts = [torch.empty_like(local) for _ in range(world)]
        dist.all_gather(parts, local.contiguous())
        out.append(torch.cat(parts))
    return out, h, (q, qd, u)


def check(rank, world, B):
    """evaluate, then on rank 0: (whether the gathered result equals the unsharded call, the shapes)"""
    (qdd, x_next), h, (q, qd, u) = evaluate(rank, world, B)
    if rank != 0:
        return None
    same = torch.equal(qdd, h.forward_dynamics(q, qd, u)) and torch.equal(x_next, h.integrator(q, qd, u, 0.01, "rk4"))
    return same, tuple(qdd.shape), tuple(x_next.shape)


def worker(rank, world, B, port, result):
    os.environ.update(MASTER_ADDR="127.0.0.1", MASTER_PORT=str(port))
    dist.init_process_group("gloo", rank=rank, world_size=world)
    try:
        r = check(rank, world, B)
        if r is not None:
            result.put(r)
    finally:
        dist.destroy_process_group()


def report(world, B, same, s1, s2):
    print(f"{world} processes (gloo), {B} knot points: qdd {s1}, x+ {s2}; "
          f"all-gathered shards {'equal' if same else 'DIFFER FROM'} the unsharded call")
    if not same:
        raise SystemExit(1)


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--world", type=int, default=2)
    p.add_argument("--batch", type=int, default=64)
    o = p.parse_args(argv)
    if "RANK" in os.environ and "WORLD_SIZE" in os.environ:  # under torchrun: one rank of its group
        rank, world = int(os.environ["RANK"]), int(os.environ["WORLD_SIZE"])
        if o.batch % world:
            raise SystemExit("--batch must be a multiple of the number of processes")
        dist.init_process_group("gloo")  # MASTER_ADDR and MASTER_PORT from torchrun
        try:
            r = check(rank, world, o.batch)
        finally:
            dist.destroy_process_group()
        if r is not None:
            report(world, o.batch, *r)
        return
    if o.batch % o.world:
        raise SystemExit("--batch must be a multiple of --world")
    ctx = mp.get_context("spawn")
    result = ctx.Queue()
    mp.start_processes(worker, args=(o.world, o.batch, free_port(), result), nprocs=o.world, start_method="spawn")
    report(o.world, o.batch, *result.get(timeout=60))


if __name__ == "__main__":
    main()

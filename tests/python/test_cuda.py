"""rbdkit.Handle(backend="cuda") in interpret mode (RBDKIT_CUDA_INTERPRET=1):
the CUDA kernels' source run on the CPU, against the CPU handle, with host
arrays and with device arrays (a NumPy stand-in exposing
__cuda_array_interface__, whose "device" memory is host memory in interpret
mode). Without a device and without interpret mode: a clear error. On a GPU
machine scripts/gpu-check.sh runs the same comparison on the device."""

import os

import numpy as np
import pytest

import rbdkit

# RBDKIT_TEST_CUDA_DEVICE=1 (scripts/gpu-check.sh): the same tests on the real device, with PyTorch or
# CuPy device arrays where one of them is installed
ON_DEVICE = os.environ.get("RBDKIT_TEST_CUDA_DEVICE") == "1"

OPS = ("inverse_dynamics", "crba", "minv", "aba", "forward_dynamics", "inverse_dynamics_gradient",
       "forward_dynamics_gradient", "integrator_gradient", "plant_step_hessian", "com", "kinetic_energy")


class StandIn:
    """a device array in interpret mode: a NumPy array behind __cuda_array_interface__"""

    def __init__(self, a):
        self.a = np.ascontiguousarray(a)

    @property
    def __cuda_array_interface__(self):
        return {"shape": self.a.shape, "typestr": self.a.dtype.str, "data": (self.a.ctypes.data, False),
                "version": 3, "strides": None}

    @classmethod
    def _rbdkit_empty(cls, shape, dtype, like):
        return cls(np.empty(shape, dtype=dtype))


@pytest.fixture
def interpret(monkeypatch):
    if not ON_DEVICE:
        monkeypatch.setenv("RBDKIT_CUDA_INTERPRET", "1")


def device_arrays():
    """(to_device, to_host) for device arrays: NumPy stand-ins in interpret mode, PyTorch or CuPy on a GPU"""
    if not ON_DEVICE:
        return StandIn, lambda d: d.a
    try:
        import torch
        if torch.cuda.is_available():
            return (lambda a: torch.from_numpy(np.ascontiguousarray(a)).cuda()), (lambda d: d.cpu().numpy())
    except ImportError:
        pass
    try:
        import cupy
        return cupy.asarray, cupy.asnumpy
    except ImportError:
        pytest.skip("on the device, device arrays need PyTorch or CuPy")


def states(h, B, seed=0):
    rng = np.random.default_rng(seed)
    rbd = h.rbd
    q = np.stack([rbd.integrate(h.model.neutral(), rng.uniform(-1, 1, h.nv)) for _ in range(B)])
    qd = rng.uniform(-1, 1, (B, h.nv))
    tau = rng.uniform(-1, 1, (B, h.nv))
    return q, qd, tau


def call(h, op, q, qd, tau, wrap=lambda a: a):
    if op in ("crba", "minv", "com"):
        return getattr(h, op)(wrap(q))
    if op == "kinetic_energy":
        return h.kinetic_energy(wrap(q), wrap(qd))
    if op == "integrator_gradient":
        return h.integrator_gradient(wrap(q), wrap(qd), wrap(tau), dt=0.01)
    if op == "plant_step_hessian":
        return h.plant_step_hessian(wrap(np.concatenate([q, qd], axis=1)), wrap(tau), dt=0.01)
    return getattr(h, op)(wrap(q), wrap(qd), wrap(tau))


def as_list(r):
    return list(r) if isinstance(r, tuple) else [r]


@pytest.mark.parametrize("robot,floating", [("iiwa", False), ("hyq", True), ("atlas", True)])
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_interpret_equals_cpu(interpret, robot, floating, dtype):
    model = rbdkit.robots.load(robot, floating_base=floating)
    cpu = rbdkit.Handle(model, dtype=dtype, threads=1)
    cu = rbdkit.Handle(model, backend="cuda", dtype=dtype)
    assert (cu.device == "interpret (CPU)") != ON_DEVICE and cpu.device is None
    to_device, to_host = device_arrays()
    q, qd, tau = states(cu, 5)
    # against the CPU engine, whose vectorised sin and cos are within an ulp of libm's (the kernels use
    # libm's in interpret mode): M⁻¹ amplifies that by cond(M) (tests/cpp/test_cuda.cpp holds the
    # kernels to 1e-12 of the serial loop, which uses libm's as well)
    amplified = ("minv", "aba", "forward_dynamics", "forward_dynamics_gradient", "integrator_gradient",
                 "plant_step_hessian")
    for op in OPS:
        if not cu.has(op):
            continue
        want = as_list(call(cpu, op, q.astype(dtype), qd.astype(dtype), tau.astype(dtype)))
        got = as_list(call(cu, op, q, qd, tau))
        dev = [to_host(d) for d in as_list(call(cu, op, q.astype(dtype), qd.astype(dtype), tau.astype(dtype),
                                                to_device))]
        assert len(got) == len(want) == len(dev), op
        for w, g, d in zip(want, got, dev):
            assert g.dtype == np.dtype(dtype) and d.dtype == np.dtype(dtype), op
            scale = max(1.0, float(np.max(np.abs(w))))
            # float32: the CPU engine and the CUDA kernels both round in float32, differently
            if dtype == "float64":
                bound = 1e-8 if op in amplified else 1e-11
            else:
                bound = 5e-2 if op == "plant_step_hessian" else 2e-3
            assert np.max(np.abs(g - w)) <= bound * scale, op
            assert np.max(np.abs(d - w)) <= bound * scale, op


def test_specialized_handle_agrees_with_the_generic_one(interpret, monkeypatch):
    # specialize=True on a backend="cuda" handle: the CUDA kernels on the robot's constants (nvcc on a GPU;
    # in interpret mode the C++ compiler, the launches emulated), for ID, M⁻¹, FD, ∇ID, ∇FD and the step
    # gradient. On a branched floating robot, by the team and by the sample kernels, they agree with the
    # generic kernels' at 1e-12 of each output's scale; an operation the instance does not hold (CRBA)
    # runs the generic kernel
    model = rbdkit.robots.load("hyq", floating_base=True)
    rng = np.random.default_rng(3)
    q = np.stack([model.random_configuration(rng) for _ in range(3)])
    qd, u = rng.uniform(-1, 1, (2, 3, model.nv))
    for kernel in ("team", "sample"):
        monkeypatch.setenv("RBDKIT_CUDA_KERNEL", kernel)
        spec, generic = (rbdkit.Handle(model, backend="cuda", specialize=s) for s in (True, False))
        assert spec.specialized and not generic.specialized
        for op, args in (("forward_dynamics_gradient", (q, qd, u)), ("inverse_dynamics", (q, qd, u)),
                         ("minv", (q,)), ("integrator_gradient", (q, qd, u, 0.01, "rk4")), ("crba", (q,))):
            got, want = getattr(spec, op)(*args), getattr(generic, op)(*args)
            for a, b in zip(got if isinstance(got, tuple) else [got], want if isinstance(want, tuple) else [want]):
                assert np.max(np.abs(a - b)) <= 1e-12 * max(1.0, np.max(np.abs(b))), (op, kernel)


def test_errors_name_the_samples(interpret):
    h = rbdkit.Handle(rbdkit.robots.load("iiwa"), backend="cuda")
    q = np.zeros((6, 7))
    q[[0, 1, 2, 4], :] = 0.3  # samples 3 and 5 stretched out: J M⁻¹ Jᵀ is singular
    with pytest.raises(ValueError, match=r"at sample 3.*2 of 6 samples, samples 3, 5"):
        h.osc_inertia(q)
    bad = np.zeros((4, 7))
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match=r"q\[2\]"):
        h.crba(bad)
    if not ON_DEVICE:  # (a stand-in's memory is the device's in interpret mode only)
        with pytest.raises(ValueError, match=r"q\[2\]"):
            h.crba(StandIn(bad))


def test_device_arrays_are_checked(interpret):
    # a device array of another dtype, a mix of host and device arrays, a wrong shape, a strided array:
    # each named. In interpret mode on NumPy stand-ins; on a GPU on PyTorch tensors, which the binding
    # reads through their own attributes (not their __cuda_array_interface__), with the same errors,
    # and a tensor that requires grad refused by name
    h = rbdkit.Handle(rbdkit.robots.load("iiwa"), backend="cuda")
    q = np.zeros((3, 7))
    if ON_DEVICE:
        torch = pytest.importorskip("torch")
        if not torch.cuda.is_available():
            pytest.skip("on the device, this test passes PyTorch's CUDA tensors")
        wrap, strided = (lambda a: torch.from_numpy(a).cuda()), torch.zeros((7, 3), dtype=torch.float64).cuda().t()
    else:
        class Strided(StandIn):
            @property
            def __cuda_array_interface__(self):
                d = StandIn.__cuda_array_interface__.fget(self)
                d["strides"] = (8, 24)
                return d
        wrap, strided = StandIn, Strided(q)
    with pytest.raises(TypeError, match="q: expected a device array of dtype float64.*got typestr '<f4'"):
        h.crba(wrap(q.astype(np.float32)))
    with pytest.raises(TypeError, match="qd: expected a device array like q .*host arrays or device arrays, not both"):
        h.inverse_dynamics(wrap(q), q, q)
    with pytest.raises(ValueError, match=r"q: expected shape \(7,\) or \(B, 7\).*got shape \(3, 6\)"):
        h.crba(wrap(np.zeros((3, 6))))
    with pytest.raises(ValueError, match="q: expected a C-contiguous device array"):
        h.crba(strided)
    M = h.crba(wrap(q))
    np.testing.assert_allclose(M.cpu().numpy() if ON_DEVICE else M.a, rbdkit.Handle(h.model).crba(q), rtol=1e-12,
                               atol=1e-12)
    if ON_DEVICE:
        with pytest.raises(TypeError, match="q: a tensor that requires grad.*detach"):
            h.crba(wrap(q).requires_grad_())


@pytest.mark.parametrize("robot", ["iiwa", "hyq_floating"])
def test_kernel_choice_from_the_environment(interpret, monkeypatch, robot):
    # RBDKIT_CUDA_KERNEL forces the team kernels (a block of threads per sample: ID, M⁻¹, FD, ∇ID, ∇FD,
    # the steps and their gradients, the step's Hessian, the costs and barriers) or the sample-per-thread ones;
    # each equals the CPU handle. A bad value is named
    name, _, floating = robot.partition("_")
    m = rbdkit.robots.load(name, floating_base=bool(floating))
    cpu = rbdkit.Handle(m)
    q, qd, tau = states(cpu, 5)
    h_des, W = np.linspace(-1, 1, 30).reshape(5, 6), np.full((5, 6), 0.5)
    lower, upper = q - 0.5, q + np.linspace(0.1, 1, q.size).reshape(q.shape)
    for kernel in ("team", "sample", "auto"):
        monkeypatch.setenv("RBDKIT_CUDA_KERNEL", kernel)
        h = rbdkit.Handle(m, backend="cuda")
        for got, ref in (((h.minv(q), h.minv(q, output_dense=False), h.forward_dynamics(q, qd, tau)),
                          (cpu.minv(q), cpu.minv(q, output_dense=False), cpu.forward_dynamics(q, qd, tau))),
                         (h.inverse_dynamics(q, qd, tau), cpu.inverse_dynamics(q, qd, tau)),
                         (h.forward_dynamics_gradient(q, qd, tau), cpu.forward_dynamics_gradient(q, qd, tau)),
                         (h.integrator_gradient(q, qd, tau, dt=0.01, integrator_type="rk4"),
                          cpu.integrator_gradient(q, qd, tau, dt=0.01, integrator_type="rk4")),
                         (h.plant_step_hessian(np.hstack([q, qd]), tau, dt=0.01, integrator_type="rk4"),
                          cpu.plant_step_hessian(np.hstack([q, qd]), tau, dt=0.01, integrator_type="rk4")),
                         ((h.plant_step(np.hstack([q, qd]), tau, dt=0.01, integrator_type="rk4"),
                           h.plant_step_gradient(np.hstack([q, qd]), tau, dt=0.01, integrator_type="trapezoidal")),
                          (cpu.plant_step(np.hstack([q, qd]), tau, dt=0.01, integrator_type="rk4"),
                           cpu.plant_step_gradient(np.hstack([q, qd]), tau, dt=0.01, integrator_type="trapezoidal"))),
                         (h.momentum_cost(q, qd, h_des, W, output_convention="mujoco"),
                          cpu.momentum_cost(q, qd, h_des, W, output_convention="mujoco")),
                         (h.joint_position_barrier(q + 0.2, lower, upper, mu=0.1),
                          cpu.joint_position_barrier(q + 0.2, lower, upper, mu=0.1))):
            for g, r in zip(got, ref):
                np.testing.assert_allclose(g, r, rtol=1e-10, atol=1e-10, err_msg=kernel)
    monkeypatch.setenv("RBDKIT_CUDA_KERNEL", "warp")
    with pytest.raises(ValueError, match="RBDKIT_CUDA_KERNEL: expected 'auto', 'team' or 'sample', got 'warp'"):
        rbdkit.Handle(m, backend="cuda")


def test_interpret_mode_refuses_gpu_arrays(monkeypatch):
    # interpret mode reads device arrays on the CPU: host memory behind __cuda_array_interface__ (the
    # stand-ins) is read, an array in a GPU's memory is refused by name (it would be read as host memory)
    monkeypatch.setenv("RBDKIT_CUDA_INTERPRET", "1")
    m = rbdkit.robots.load("iiwa")
    h, cpu = rbdkit.Handle(m, backend="cuda"), rbdkit.Handle(m)
    q, qd, tau = states(h, 3)
    np.testing.assert_allclose(h.inverse_dynamics(StandIn(q), StandIn(qd), StandIn(tau)).a,
                               cpu.inverse_dynamics(q, qd, tau), rtol=1e-12, atol=1e-12)
    if not ON_DEVICE:
        return
    torch = pytest.importorskip("torch")
    dq, dqd, dtau = (torch.from_numpy(a).cuda() for a in (q, qd, tau))
    with pytest.raises(ValueError, match="inverse_dynamics: q: an array in GPU memory.*interpret mode"):
        h.inverse_dynamics(dq, dqd, dtau)
    import rbdkit.torch as rt
    with pytest.raises(ValueError, match="q: an array in GPU memory"):
        rt.Handle(m, backend="cuda").inverse_dynamics(dq, dqd, dtau)


def test_no_device_is_a_clear_error(monkeypatch):
    monkeypatch.delenv("RBDKIT_CUDA_INTERPRET", raising=False)
    compiled, devices = rbdkit.cuda_available()
    if compiled and devices > 0:
        assert rbdkit.Handle(rbdkit.robots.load("iiwa"), backend="cuda").device not in (None, "interpret (CPU)")
        return
    with pytest.raises(RuntimeError, match="RBDKIT_CUDA_INTERPRET=1") as e:
        rbdkit.Handle(rbdkit.robots.load("iiwa"), backend="cuda")
    assert ("no CUDA device" if compiled else "no CUDA kernels") in str(e.value)
    with pytest.raises(ValueError, match="backend: expected 'cpu' or 'cuda'"):
        rbdkit.Handle(rbdkit.robots.load("iiwa"), backend="gpu")


@pytest.mark.skipif(ON_DEVICE, reason="scripts/gpu-check.sh runs the benchmark itself on the device")
def test_bench_gpu_script(tmp_path):
    """bench/gpu.py in interpret mode, on the smallest batches: it runs, writes its table, and skips a B
    whose data would exceed --max-gb rather than allocating it"""
    import subprocess
    import sys
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    out = tmp_path / "gpu.md"
    r = subprocess.run([sys.executable, os.path.join(root, "bench", "gpu.py"), "--robots", "iiwa", "--arrays", "none",
                        "--budget", "0.001", "--max-gb", "1e-5", "--kernels", "--out", str(out)],
                       env=dict(os.environ, RBDKIT_CUDA_INTERPRET="1"), capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    rows = [line.split("|")[1:-1] for line in out.read_text().splitlines() if line.startswith("| iiwa |")]
    assert len(rows) == 2 * 8 * 7  # two dtypes, eight operations, seven batch sizes
    # --kernels: the sample and team kernel columns ("-" without device arrays)
    assert "| sample kernel | team kernel |" in out.read_text()
    assert all(len(r) == 10 and r[8].strip() == r[9].strip() == "-" for r in rows)
    # iiwa's ID at B = 16: 16 x 28 values in and out, 3.6 kB, under 10 kB: measured
    id16 = [r for r in rows if r[2].strip() == "ID" and r[3].strip() == "16"]
    assert len(id16) == 2 and all(float(r[5]) > 0 and float(r[6]) > 0 for r in id16)
    # the Euler step Hessian of iiwa is 14 x 21 x 21 values (49 kB) a sample: skipped at every B
    hess = [r for r in rows if r[2].strip() == "euler ∇²step"]
    assert len(hess) == 14 and all("over --max-gb" in r[7] for r in hess)
    # the step's value, the costs and the barrier, named by --ops (their team kernels' rule is set from
    # these rows)
    cost_ops = "integrator,momentum_cost,quadratic_state_cost_tangent,joint_position_barrier"
    r = subprocess.run([sys.executable, os.path.join(root, "bench", "gpu.py"), "--robots", "iiwa", "--arrays", "none",
                        "--budget", "0.001", "--batches", "1,16", "--ops", cost_ops, "--kernels", "--out", str(out)],
                       env=dict(os.environ, RBDKIT_CUDA_INTERPRET="1"), capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    rows = [line.split("|")[1:-1] for line in out.read_text().splitlines() if line.startswith("| iiwa |")]
    assert sorted({r[2].strip() for r in rows}) == ["momentum cost", "q barrier", "rk4 step", "state cost"]
    assert len(rows) == 2 * 4 * 2 and all(float(r[5]) > 0 and float(r[6]) > 0 for r in rows)
    # --ops and --batches narrow the table; a bad batch size is named
    script = [sys.executable, os.path.join(root, "bench", "gpu.py"), "--robots", "iiwa", "--arrays", "none",
              "--budget", "0.001", "--ops", "minv", "--out", str(out)]
    env = dict(os.environ, RBDKIT_CUDA_INTERPRET="1")
    r = subprocess.run(script + ["--batches", "1,16"], env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    rows = [line.split("|")[1:-1] for line in out.read_text().splitlines() if line.startswith("| iiwa |")]
    assert [(r[1].strip(), r[2].strip(), r[3].strip()) for r in rows] == [
        (dt, "M⁻¹", b) for dt in ("float32", "float64") for b in ("1", "16")]
    r = subprocess.run(script + ["--batches", "1,0"], env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 2 and "--batches: expected positive batch sizes, got '1,0'" in r.stderr

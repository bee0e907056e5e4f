"""rbdkit generate: per-robot headers against the library. For the bundled
robots and the joint-type test models, the generated header is compiled into a
small program with g++ (and clang) as C++17 with only rbdkit's include folder
on the path, run on random states, and every entry point compared with
rbdkit.Handle at 1e-12; valgrind finds no read of uninitialised memory (the
stack workspace is not zero-filled); nvcc compiles it inside a kernel (compile
only: CI has no GPU). Then the CLI and its errors."""

import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

import rbdkit

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
URDF = os.path.join(ROOT, "tests", "urdf")
SCHEMES = ["euler", "semi_implicit_euler", "midpoint", "rk4", "trapezoidal", "constant_acceleration"]
MODELS = [("iiwa", False), ("hyq", True), ("atlas", True), ("spherical", False), ("helical", False), ("mimic", False),
          ("planar", False), ("mixed", True)]


def load(name, floating):
    if name in rbdkit.robots.names():
        return rbdkit.robots.load(name, floating_base=floating)
    return rbdkit.Model.from_urdf(os.path.join(URDF, name + ".urdf"), floating_base=floating)


def compiler(name):
    path = shutil.which(name)
    if path is None and os.environ.get("CI") == "true":
        pytest.fail(f"{name} not found: CI compiles the generated headers with it")
    if path is None:
        pytest.skip(f"{name} not found")
    return path


def c_array(name, values, ctype="double"):
    return f"const {ctype} {name}[] = {{{', '.join(repr(float(v)) for v in np.ravel(values))}}};\n"


PROGRAM = """#include "{name}.hpp"
#include <cstdio>
using G = rbdkit_generated::{name};
{arrays}
template <class S> void print(const char* what, const S* x, int n) {{
  std::printf("%s", what);
  for (int i = 0; i < n; ++i) std::printf(" %.17g", double(x[i]));
  std::printf("\\n");
}}
int main() {{
  const int nq = G::nq, nv = G::nv;
  double tau[nv], qdd[nv], M[nv * nv], D1[nv * nv], D2[nv * nv], x[nq + nv], AB[2 * nv * 3 * nv];
  G::inverse_dynamics(q, qd, qdd_in, -9.81, tau);
  print("inverse_dynamics", tau, nv);
  G::inverse_dynamics(q, qd, static_cast<const double*>(nullptr), -3.0, tau);
  print("inverse_dynamics_no_qdd", tau, nv);
  if (!G::aba(q, qd, u, -9.81, qdd)) return 1;
  print("aba", qdd, nv);
  G::crba(q, M);
  print("crba", M, nv * nv);
  if (!G::minv(q, M)) return 1;
  print("minv", M, nv * nv);
  G::inverse_dynamics_gradient(q, qd, qdd_in, -9.81, D1, D2);
  print("dtau_dq", D1, nv * nv);
  print("dtau_dqd", D2, nv * nv);
  if (!G::forward_dynamics_gradient(q, qd, u, -9.81, D1, D2)) return 1;
  print("dqdd_dq", D1, nv * nv);
  print("dqdd_dqd", D2, nv * nv);
  for (int type = 0; type < 6; ++type) {{
    if (!G::integrator_gradient(q, qd, u, 0.01, type, x, AB)) return 1;
    char label[32];
    std::snprintf(label, sizeof label, "x_next%d", type);
    print(label, x, nq + nv);
    std::snprintf(label, sizeof label, "AB%d", type);
    print(label, AB, 2 * nv * 3 * nv);
  }}
  float qf[nq], qdf[nv], tauf[nv];  // float: the same templates
  for (int i = 0; i < nq; ++i) qf[i] = float(q[i]);
  for (int i = 0; i < nv; ++i) qdf[i] = float(qd[i]);
  G::inverse_dynamics(qf, qdf, static_cast<const float*>(nullptr), -9.81f, tauf);
  print("inverse_dynamics_f32", tauf, nv);
  return 0;
}}
"""


def build(cxx, src, exe, flags=("-O1", "-Wall", "-Wextra", "-Werror")):
    """compile the program src (next to its generated header) as C++17 with only rbdkit's include folder"""
    r = subprocess.run([cxx, "-std=c++17", *flags, "-I", rbdkit.include_dir(), "-I", str(src.parent), str(src), "-o",
                        str(exe)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-4000:]


def run(*command):
    """the stdout of a program that must succeed"""
    r = subprocess.run([str(c) for c in command], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-4000:]
    return r.stdout


def run_generated(model, name, tmp_path, cxx, q, qd, qdd, u):
    """{label: values} printed by the generated header's program (PROGRAM) compiled with cxx"""
    rbdkit.generate(model, name, tmp_path / f"{name}.hpp", source="test")
    arrays = c_array("q", q) + c_array("qd", qd) + c_array("qdd_in", qdd) + c_array("u", u)
    src = tmp_path / f"{name}_main.cpp"
    src.write_text(PROGRAM.format(name=name, arrays=arrays))
    exe = tmp_path / f"{name}_{os.path.basename(cxx)}"
    build(cxx, src, exe)
    return {line.split()[0]: np.array([float(v) for v in line.split()[1:]]) for line in run(exe).splitlines()}


def close(got, want, tol=1e-12):
    want = np.ravel(want)
    assert got.shape == want.shape
    return np.max(np.abs(got - want)) <= tol * max(1.0, np.max(np.abs(want)))


@pytest.mark.parametrize("name,floating", MODELS)
def test_generated_header_agrees_with_the_library(name, floating, tmp_path):
    model = load(name, floating)
    h = rbdkit.Handle(model, threads=1)
    rng = np.random.default_rng(0)
    q = model.random_configuration(rng)
    qd, qdd, u = (rng.uniform(-1, 1, model.nv) for _ in range(3))
    out = run_generated(model, "Robot", tmp_path, compiler("g++"), q, qd, qdd, u)
    assert close(out["inverse_dynamics"], h.inverse_dynamics(q, qd, qdd))
    assert close(out["inverse_dynamics_no_qdd"], h.inverse_dynamics(q, qd, gravity=-3.0))
    assert close(out["aba"], h.aba(q, qd, u))
    assert close(out["crba"], h.crba(q))
    assert close(out["minv"], h.minv(q))
    D = h.inverse_dynamics_gradient(q, qd, qdd)
    assert close(out["dtau_dq"], D[:, :model.nv]) and close(out["dtau_dqd"], D[:, model.nv:])
    Dq, Dqd = h.forward_dynamics_gradient(q, qd, u)
    assert close(out["dqdd_dq"], Dq) and close(out["dqdd_dqd"], Dqd)
    for k, scheme in enumerate(SCHEMES):
        AB = h.integrator_gradient(q, qd, u, 0.01, scheme)
        assert close(out[f"x_next{k}"], h.integrator(q, qd, u, 0.01, scheme)), scheme
        assert close(out[f"AB{k}"], AB), scheme
    hf = rbdkit.Handle(model, dtype="float32", threads=1)
    want = hf.inverse_dynamics(q.astype(np.float32), qd.astype(np.float32))
    assert close(out["inverse_dynamics_f32"], want, tol=1e-4)


@pytest.mark.parametrize("name,floating", [("hyq", True), ("mimic", False)])
def test_generated_code_reads_no_uninitialised_memory(name, floating, tmp_path):
    # the generated calls keep their workspace on the stack without zero-filling it: valgrind's memcheck
    # on every entry point and scheme (a floating base, a mimic model's dense paths)
    valgrind = compiler("valgrind")
    model = load(name, floating)
    rng = np.random.default_rng(2)
    q = model.random_configuration(rng)
    qd, qdd, u = (rng.uniform(-1, 1, model.nv) for _ in range(3))
    rbdkit.generate(model, "Robot", tmp_path / "Robot.hpp")
    arrays = c_array("q", q) + c_array("qd", qd) + c_array("qdd_in", qdd) + c_array("u", u)
    (tmp_path / "main.cpp").write_text(PROGRAM.format(name="Robot", arrays=arrays))
    exe = tmp_path / "prog"
    build(compiler("g++"), tmp_path / "main.cpp", exe, flags=("-O0", "-g"))
    r = subprocess.run([valgrind, "-q", "--error-exitcode=9", "--track-origins=yes", str(exe)], capture_output=True,
                       text=True)
    assert r.returncode == 0 and "uninitialised" not in r.stderr, r.stderr[-4000:]


RUNTIME = """#include "Robot.hpp"
#include <cstdio>
using G = rbdkit_generated::Robot;
{arrays}
int main() {{
  double tau[G::nv], AB[2 * G::nv * 3 * G::nv], x[G::nq + G::nv];
  G::inverse_dynamics(pi, q, qd, qdd_in, -9.81, tau);
  for (double t : tau) std::printf("%.17g ", t);
  std::printf("\\n");
  if (!G::integrator_gradient(pi, q, qd, qdd_in, 0.01, 3, x, AB)) return 1;
  for (double a : AB) std::printf("%.17g ", a);
  std::printf("\\n");
}}
"""


@pytest.mark.parametrize("name,floating", [("iiwa", False), ("hyq", True)])
def test_generated_header_with_runtime_inertias(name, floating, tmp_path):
    # --runtime-inertias: pi (10·nb) is the first argument; with other parameters than the file's the
    # results equal a library model with those parameters
    model = load(name, floating)
    rng = np.random.default_rng(3)
    pi = model.inertial_parameters()
    pi2 = np.concatenate([p * rng.uniform(0.8, 1.25) for p in pi.reshape(-1, 10)])  # each body scaled: consistent
    q = model.random_configuration(rng)
    qd, qdd = rng.uniform(-1, 1, model.nv), rng.uniform(-1, 1, model.nv)
    text = rbdkit.generate(model, "Robot", tmp_path / "Robot.hpp", runtime_inertias=True)
    assert "const S* pi, const S* q," in text and "pi[" in text
    arrays = c_array("pi", pi2) + c_array("q", q) + c_array("qd", qd) + c_array("qdd_in", qdd)
    (tmp_path / "main.cpp").write_text(RUNTIME.format(arrays=arrays))
    exe = tmp_path / "prog"
    build(compiler("g++"), tmp_path / "main.cpp", exe)
    tau, AB = (np.array([float(v) for v in line.split()]) for line in run(exe).splitlines())
    h2 = rbdkit.Handle(model.with_inertial_parameters(pi2), threads=1)
    assert close(tau, h2.inverse_dynamics(q, qd, qdd))
    assert close(AB, h2.integrator_gradient(q, qd, qdd, 0.01, "rk4"))
    assert not close(tau, rbdkit.Handle(model, threads=1).inverse_dynamics(q, qd, qdd), tol=1e-6)


def test_generated_header_compiles_with_clang(tmp_path):
    model = load("hyq", True)
    rng = np.random.default_rng(1)
    q = model.random_configuration(rng)
    qd, qdd, u = (rng.uniform(-1, 1, model.nv) for _ in range(3))
    out = run_generated(model, "HyQ", tmp_path, compiler("clang++"), q, qd, qdd, u)
    h = rbdkit.Handle(model, threads=1)
    assert close(out["crba"], h.crba(q)) and close(out["AB3"], h.integrator_gradient(q, qd, u, 0.01, "rk4"))


KERNEL = """#include "Iiwa.hpp"
using G = rbdkit_generated::Iiwa;
// one sample per thread: the generated functions inside a user kernel
__global__ void step(const double* q, const double* qd, const double* u, double* x, double* AB, double* tau, int B) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= B) return;
  G::inverse_dynamics(q + i * G::nq, qd + i * G::nv, u + i * G::nv, -9.81, tau + i * G::nv);
  G::integrator_gradient(q + i * G::nq, qd + i * G::nv, u + i * G::nv, 0.01, 3, x + i * (G::nq + G::nv),
                         AB + i * 2 * G::nv * 3 * G::nv);
}
"""


def test_generated_header_compiles_with_nvcc_in_a_kernel(tmp_path):
    nvcc = shutil.which("nvcc") or ("/usr/local/cuda/bin/nvcc" if os.path.exists("/usr/local/cuda/bin/nvcc") else None)
    if nvcc is None:
        compiler("nvcc")
    rbdkit.generate(rbdkit.robots.load("iiwa"), "Iiwa", tmp_path / "Iiwa.hpp")
    (tmp_path / "kernel.cu").write_text(KERNEL)
    r = subprocess.run([nvcc, "-std=c++17", "-arch=compute_90", "--ptx", "-I", rbdkit.include_dir(), "-I",
                        str(tmp_path), str(tmp_path / "kernel.cu"), "-o", str(tmp_path / "kernel.ptx")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-4000:]
    assert ".entry" in (tmp_path / "kernel.ptx").read_text()


def test_cli_and_errors(tmp_path):
    out = tmp_path / "Iiwa.hpp"
    r = subprocess.run([sys.executable, "-m", "rbdkit", "generate", "iiwa", "--name", "Iiwa", "-o", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "struct Iiwa {" in out.read_text() and "nq = 7, nv = 7, nb = 7" in out.read_text()
    urdf = os.path.join(URDF, "spherical.urdf")
    r = subprocess.run([sys.executable, "-m", "rbdkit", "generate", urdf, "--floating-base", "--name", "S", "-o",
                        str(tmp_path / "S.hpp")], capture_output=True, text=True)
    assert r.returncode == 0 and "rbd::kFree" in (tmp_path / "S.hpp").read_text(), r.stderr
    r = subprocess.run([sys.executable, "-m", "rbdkit", "generate", "iiwa", "--runtime-inertias", "--name", "R", "-o",
                        str(tmp_path / "R.hpp")], capture_output=True, text=True)
    assert r.returncode == 0 and "const S* pi, const S* q," in (tmp_path / "R.hpp").read_text(), r.stderr
    for args, message in ((["iiwa", "--name", "3d", "-o", str(out)], "name: expected a C++ identifier"),
                          (["nope", "--name", "X", "-o", str(out)], "neither a file nor a bundled robot"),
                          (["iiwa", "--name", "X", "-o", str(tmp_path / "no" / "X.hpp")], "does not exist")):
        r = subprocess.run([sys.executable, "-m", "rbdkit", "generate", *args], capture_output=True, text=True)
        assert r.returncode == 2 and message in r.stderr, (args, r.stderr)
    for bad in ("class", "nq", "bodies", "rbd"):  # a keyword, the struct's members, a namespace it uses
        with pytest.raises(ValueError, match="not a keyword or one of the struct's members"):
            rbdkit.generate(rbdkit.robots.load("iiwa"), bad)
    # names from the file stay inside their comment
    urdf = open(os.path.join(URDF, "spherical.urdf")).read()
    model = rbdkit.Model.from_urdf_string(urdf.replace('"l1"', '"a&#10;int x = ;"'))  # the link and its references
    text = rbdkit.generate(model, "Injected")
    assert "int x = ;" not in [line.strip() for line in text.splitlines()] and "a?int x = ;" in text
    with pytest.raises(ValueError, match="no moving body"):
        rbdkit.generate(rbdkit.Model.from_urdf_string('<robot name="r"><link name="a"/></robot>'), "Empty")
    with pytest.raises(TypeError, match="model: expected an rbdkit.Model"):
        rbdkit.generate("iiwa", "X")
    with pytest.raises(ValueError, match="name: expected a C\\+\\+ identifier"):
        rbdkit.generate(rbdkit.robots.load("iiwa"), "a-b")


# ---- Handle(model, specialize=True): the compiled per-robot instance inside rbdkit

SPECIALIZED_CALLS = [  # (operation, arguments after the state) of every kernel an instance has
    ("inverse_dynamics", lambda q, qd, u, f: (q, qd, u), {}),
    ("inverse_dynamics", lambda q, qd, u, f: (q, qd, u), {"f_ext": True}),
    ("nonlinear_effects", lambda q, qd, u, f: (q, qd), {}),
    ("generalized_gravity", lambda q, qd, u, f: (q,), {}),
    ("crba", lambda q, qd, u, f: (q,), {}),
    ("minv", lambda q, qd, u, f: (q,), {}),
    ("aba", lambda q, qd, u, f: (q, qd, u), {"f_ext": True}),
    ("forward_dynamics", lambda q, qd, u, f: (q, qd, u), {}),
    ("inverse_dynamics_gradient", lambda q, qd, u, f: (q, qd, u), {}),
    ("forward_dynamics_gradient", lambda q, qd, u, f: (q, qd, u), {"f_ext": True}),
    ("integrator", lambda q, qd, u, f: (q, qd, u, 0.01, "rk4"), {"f_ext": True}),
    ("integrator_gradient", lambda q, qd, u, f: (q, qd, u, 0.01, "midpoint"), {}),
]


@pytest.mark.parametrize("name,floating", [("iiwa", False), ("hyq", True), ("mimic", False)])
def test_specialized_handle_agrees_with_the_generic_one(name, floating):
    # the instance's kernels run the float64 serial loop (single samples; a batch, B = 3, runs on the
    # engine either way); they agree with the generic kernels at 1e-12 of each output's scale, f_ext
    # included
    compiler("c++")
    model = load(name, floating)
    spec, generic = rbdkit.Handle(model, specialize=True), rbdkit.Handle(model)
    assert spec.specialized and not generic.specialized
    rng = np.random.default_rng(5)
    for B in (None, 3):
        n = 1 if B is None else B
        q = np.stack([model.random_configuration(rng) for _ in range(n)])
        qd, u = rng.uniform(-1, 1, (2, n, model.nv))
        f = 0.3 * rng.uniform(-1, 1, (n, model.nb, 6))
        if B is None:
            q, qd, u, f = q[0], qd[0], u[0], f[0]
        for op, args, kw in SPECIALIZED_CALLS:
            kwargs = {"f_ext": f} if kw.get("f_ext") else {}
            got, want = (getattr(h, op)(*args(q, qd, u, f), **kwargs) for h in (spec, generic))
            for a, b in zip(got if isinstance(got, tuple) else [got], want if isinstance(want, tuple) else [want]):
                # relative to the output's scale (the instance and the library may round differently:
                # other flags, and the compiler's contraction of products into FMAs)
                assert np.max(np.abs(a - b)) <= 1e-12 * max(1.0, np.max(np.abs(b))), f"{op} B={B}"


def test_specialize_falls_back_with_a_warning(monkeypatch, tmp_path):
    # no compiler: one RuntimeWarning that says why, the generic kernels, the same numbers
    monkeypatch.setenv("RBDKIT_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("CXX", str(tmp_path / "no-such-compiler"))
    model = rbdkit.robots.load("iiwa")
    with pytest.warns(RuntimeWarning, match="specialize=True fell back to the generic kernels: .*no C\\+\\+ compiler"):
        h = rbdkit.Handle(model, specialize=True)
    assert not h.specialized
    q = model.random_configuration(np.random.default_rng(0))
    np.testing.assert_array_equal(h.crba(q), rbdkit.Handle(model).crba(q))
    import warnings
    with warnings.catch_warnings():  # once per reason
        warnings.simplefilter("error")
        assert not rbdkit.Handle(model, specialize=True).specialized
    with pytest.raises(TypeError, match="specialize: expected True or False"):
        rbdkit.Handle(model, specialize="yes")
    # a float32 handle computes every call on the batch engine: it says so
    with pytest.warns(RuntimeWarning, match="float32 handle runs every call on the batch engine"):
        assert not rbdkit.Handle(model, dtype="float32", specialize=True).specialized


def test_the_checked_in_iiwa_header_is_current():
    """cuda/generated_iiwa.hpp (cuda/stage_latency.cu times the kernels on its constants) is
    `rbdkit generate iiwa --name Iiwa` of this tree"""
    with open(os.path.join(ROOT, "cuda", "generated_iiwa.hpp")) as f:
        checked_in = f.read()
    assert checked_in == rbdkit.generate(rbdkit.robots.load("iiwa"), "Iiwa", source="iiwa"), \
        "cuda/generated_iiwa.hpp is stale: python3 -m rbdkit generate iiwa --name Iiwa -o cuda/generated_iiwa.hpp"


// rbdkit._core: the trajectory optimiser (include/rbdkit/solver/solver.hpp). The
// Python layer (python/rbdkit/_solver.py) checks the arguments and passes the
// problem and options as dicts; the solve runs with the GIL released and
// takes it back only for Python callbacks (progress, or derivatives from a
// Python handle).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/function.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <cstring>
#include <memory>

#include "arrays.hpp"
#include "rbdkit/solver/solver.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using rbd_py::In;

namespace {

using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

Eigen::VectorXd vec(const nb::dict& d, const char* key) {
  if (!d.contains(key) || d[key].is_none()) return {};
  const In a = nb::cast<In>(d[key]);
  return Eigen::Map<const Eigen::VectorXd>(a.data(), static_cast<long>(a.size()));
}

Eigen::Vector3d vec3(const nb::dict& d, const char* key, const Eigen::Vector3d& fallback) {
  const Eigen::VectorXd v = vec(d, key);
  if (v.size() == 0) return fallback;
  if (v.size() != 3) throw std::invalid_argument(std::string(key) + ": expected 3 values");
  return v;
}

RowMat mat(const std::optional<In>& a) {
  if (!a || a->size() == 0) return {};
  const long rows = static_cast<long>(a->shape(0)), cols = static_cast<long>(a->size()) / rows;
  return Eigen::Map<const RowMat>(a->data(), rows, cols);
}

// d[key] as T (fallback when absent); a value T cannot hold (an integer
// beyond int's range) names the key rather than nanobind's bad_cast
template <typename T> T get(const nb::dict& d, const char* key, T fallback) {
  if (!d.contains(key)) return fallback;
  T v;
  if (!nb::try_cast<T>(d[key], v))
    throw std::invalid_argument(std::string(key) + ": expected a value of the C++ option's type (an int within "
                                "±2147483647 or a float), got " + nb::cast<std::string>(nb::repr(d[key])));
  return v;
}

nb::ndarray<nb::numpy, double> to_numpy(const double* data, std::vector<size_t> shape) {
  size_t n = 1;
  for (size_t s : shape) n *= s;
  double* buf = new double[n];
  std::memcpy(buf, data, n * sizeof(double));
  nb::capsule owner(buf, [](void* p) noexcept { delete[] static_cast<double*>(p); });
  return nb::ndarray<nb::numpy, double>(buf, shape.size(), shape.data(), owner);
}

// derivatives by Python callables (a Python rbdkit.Handle), rollouts by the C++ handle
class PythonSteps : public rbd::HandleSteps {
 public:
  PythonSteps(rbd::Handle& h, double dt, const std::string& type, double g, nb::object grad, nb::object hess)
      : rbd::HandleSteps(h, dt, type, g), nq_(h.model().nq), nv_(h.model().nv), grad_(grad), hess_(hess) {}
  void step_gradient(long B, const double* x, const double* u, double* AB) override {
    call(grad_, B, x, u, AB, static_cast<size_t>(2 * nv_) * 3 * nv_, "plant_step_gradient");
  }
  void step_hessian(long B, const double* x, const double* u, double* H) override {
    call(hess_, B, x, u, H, static_cast<size_t>(2 * nv_) * 3 * nv_ * 3 * nv_, "plant_step_hessian");
  }

 private:
  void call(nb::object& fn, long B, const double* x, const double* u, double* out, size_t per, const char* what) {
    nb::gil_scoped_acquire gil;
    if (fn.is_none()) throw std::invalid_argument(std::string("handle: it has no ") + what);
    nb::object r = fn(to_numpy(x, {size_t(B), size_t(nq_ + nv_)}), to_numpy(u, {size_t(B), size_t(nv_)}));
    const auto a = nb::cast<nb::ndarray<const double, nb::c_contig, nb::device::cpu>>(r);
    if (a.size() != B * per)
      throw std::invalid_argument(std::string("handle: ") + what + " returned " + std::to_string(a.size()) +
                                  " values, expected " + std::to_string(B * per));
    std::memcpy(out, a.data(), B * per * sizeof(double));
  }
  int nq_, nv_;
  nb::object grad_, hess_;
};

nb::dict record(const rbd::IterationRecord& r) {
  nb::dict d;
  d["iteration"] = r.iteration, d["cost"] = r.cost, d["merit"] = r.merit, d["violation"] = r.violation;
  d["step"] = r.step, d["reg"] = r.reg, d["mu"] = r.mu, d["grad_norm"] = r.grad_norm;
  d["expected"] = r.expected, d["actual"] = r.actual, d["time"] = r.time;
  d["derivatives_time"] = r.derivatives_time;
  return d;
}

}  // namespace

void bind_solver(nb::module_& m) {
  // problem, options: dicts with the fields of rbd::TrajectoryProblem / rbd::SolverOptions
  m.def(
      "solve_trajectory",
      [](const rbd::Model& model, const nb::dict& prob, const nb::dict& opts, std::optional<In> U_init,
         std::optional<In> X_init, std::optional<In> K_init, nb::object py_grad, nb::object py_hess,
         nb::object progress) {
        rbd::TrajectoryProblem p;
        p.horizon = get<int>(prob, "horizon", 0);
        p.dt = get<double>(prob, "dt", 0.01);
        p.integrator = get<std::string>(prob, "integrator", "rk4");
        p.gravity = get<double>(prob, "gravity", -9.81);
        p.x0 = vec(prob, "x0");
        p.x_ref = vec(prob, "x_ref"), p.Q = vec(prob, "Q"), p.Q_terminal = vec(prob, "Q_terminal");
        p.u_ref = vec(prob, "u_ref"), p.R = vec(prob, "R");
        p.ee = get<bool>(prob, "ee", false);
        p.ee_body = get<int>(prob, "ee_body", -1);
        p.ee_offset = vec3(prob, "ee_offset", Eigen::Vector3d::Zero());
        p.ee_target = vec3(prob, "ee_target", Eigen::Vector3d::Zero());
        p.W_ee = vec3(prob, "W_ee", Eigen::Vector3d::Zero());
        p.W_ee_terminal = vec3(prob, "W_ee_terminal", Eigen::Vector3d::Zero());
        p.com = get<bool>(prob, "com", false);
        p.com_target = vec3(prob, "com_target", Eigen::Vector3d::Zero());
        p.W_com = vec3(prob, "W_com", Eigen::Vector3d::Zero());
        p.W_com_terminal = vec3(prob, "W_com_terminal", Eigen::Vector3d::Zero());
        p.position_limits = get<bool>(prob, "position_limits", true);
        p.velocity_limits = get<bool>(prob, "velocity_limits", true);
        p.torque_limits = get<bool>(prob, "torque_limits", true);
        p.q_lower = vec(prob, "q_lower"), p.q_upper = vec(prob, "q_upper");
        p.v_limit = vec(prob, "v_limit"), p.u_limit = vec(prob, "u_limit");
        rbd::SolverOptions o;
        o.max_iterations = get<int>(opts, "max_iterations", o.max_iterations);
        o.ddp = get<bool>(opts, "ddp", o.ddp);
        o.mu_init = get<double>(opts, "mu_init", o.mu_init);
        o.mu_min = get<double>(opts, "mu_min", o.mu_min);
        o.mu_factor = get<double>(opts, "mu_factor", o.mu_factor);
        o.reg_init = get<double>(opts, "reg_init", o.reg_init);
        o.reg_min = get<double>(opts, "reg_min", o.reg_min);
        o.reg_max = get<double>(opts, "reg_max", o.reg_max);
        o.reg_factor = get<double>(opts, "reg_factor", o.reg_factor);
        o.tol_cost = get<double>(opts, "tol_cost", o.tol_cost);
        o.tol_grad = get<double>(opts, "tol_grad", o.tol_grad);
        o.line_search_steps = get<int>(opts, "line_search_steps", o.line_search_steps);
        if (!progress.is_none())
          o.callback = [progress](const rbd::IterationRecord& r) {
            nb::gil_scoped_acquire gil;
            progress(record(r));
          };
        std::vector<Eigen::MatrixXd> K0;
        if (K_init && K_init->size()) {
          const long N = static_cast<long>(K_init->shape(0)), r = static_cast<long>(K_init->shape(1)),
                     c = static_cast<long>(K_init->shape(2));
          for (long k = 0; k < N; ++k) K0.push_back(Eigen::Map<const RowMat>(K_init->data() + k * r * c, r, c));
        }
        const RowMat U0 = mat(U_init), X0 = mat(X_init);
        std::vector<std::string> algos = {"integrator_gradient", "state_costs", "ee_pos_cost", "barriers"};
        if (get<bool>(opts, "ddp", false) && py_hess.is_none()) algos.push_back("plant_step_hessian");
        if (p.com) algos.push_back("com_cost");
        rbd::SolverResult r;
        {
          rbd::Handle h(model, algos, get<int>(opts, "threads", 0));  // threads: an rbdkit.Handle's
          std::unique_ptr<rbd::HandleSteps> steps;
          if (py_grad.is_none())
            steps = std::make_unique<rbd::HandleSteps>(h, p.dt, p.integrator, p.gravity);
          else
            steps = std::make_unique<PythonSteps>(h, p.dt, p.integrator, p.gravity, py_grad, py_hess);
          nb::gil_scoped_release release;
          r = rbd::solve_trajectory(model, *steps, h, p, o, U0, X0, K0);
        }
        const size_t N = static_cast<size_t>(r.U.rows()), nv = static_cast<size_t>(r.U.cols());
        const size_t nx = static_cast<size_t>(r.X.cols());
        std::vector<double> K(N * nv * 2 * nv);
        for (size_t k = 0; k < N; ++k)
          Eigen::Map<RowMat>(K.data() + k * nv * 2 * nv, nv, 2 * nv) = r.K[k];
        nb::dict out;
        out["X"] = to_numpy(r.X.data(), {N + 1, nx});
        out["U"] = to_numpy(r.U.data(), {N, nv});
        out["K"] = to_numpy(K.data(), {N, nv, 2 * nv});
        out["k"] = to_numpy(r.k.data(), {N, nv});
        nb::list log;
        for (const rbd::IterationRecord& rec : r.log) log.append(record(rec));
        out["log"] = log;
        out["status"] = r.status, out["converged"] = r.converged, out["iterations"] = r.iterations;
        out["cost"] = r.cost, out["merit"] = r.merit, out["violation"] = r.violation, out["mu"] = r.mu;
        out["time"] = r.time, out["derivatives_time"] = r.derivatives_time;
        out["derivative_knots"] = r.derivative_knots;
        return out;
      },
      "model"_a, "problem"_a, "options"_a, "U_init"_a.none(), "X_init"_a.none(), "K_init"_a.none(),
      "step_gradient"_a.none(), "step_hessian"_a.none(), "progress"_a.none());
  m.def("reach_radius", [](const rbd::Model& model, int body, In offset) {
    return rbd::reach_radius(model, body, Eigen::Map<const Eigen::Vector3d>(offset.data()));
  });
}

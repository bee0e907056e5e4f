// The batched CPU engine (engine.hpp): the public entry points, and the
// table of the registered operations' routes, compiled in
// src/batch/engine/routes_<dtype>.cpp (the pool, the per-thread buffers and
// op_route are in src/batch/engine/engine_impl.hpp).
#include "rbdkit/batch/engine.hpp"

#include <sstream>
#include <stdexcept>
#include <thread>

#include "engine/engine_impl.hpp"
#include "rbdkit/plant/integrators.hpp"

namespace rbd {
namespace engine_detail {
// compiled in src/batch/engine/routes_<dtype>.cpp, not here
extern template void add_routes<double>(OpRoute<double>*);
extern template void add_routes<float>(OpRoute<float>*);
}  // namespace engine_detail

namespace {
using namespace engine_detail;

// one route per operation of ops::AllOps, in its order
template <typename T> const OpRoute<T>* routes() {
  static const struct Table {
    OpRoute<T> fn[ops::AllOps::size] = {};
    Table() { add_routes<T>(fn); }
  } table;
  return table.fn;
}

template <typename T> EngineT<T>& impl_as(Engine::Impl* impl, const char* what) {
  const char* want = sizeof(T) == sizeof(double) ? "float64" : "float32";
  if (impl->dtype != want) {
    std::ostringstream os;
    os << what << ": the arrays are " << want << " but the engine was built for " << impl->dtype;
    throw std::invalid_argument(os.str());
  }
  return static_cast<EngineT<T>&>(*impl);
}

void check_type(const char* what, int type) {
  if (type < kEuler || type > kConstantAcceleration) {
    std::ostringstream os;
    os << what << ": integrator_type: expected 0..5 (euler, semi_implicit_euler, midpoint, rk4, trapezoidal, "
          "constant_acceleration), got "
       << type;
    throw std::invalid_argument(os.str());
  }
}
template <typename T> void check_dt(const char* what, T dt) {
  if (!(dt > 0) || !(dt <= T(kMaxTimeStep))) {
    std::ostringstream os;
    os << what << ": dt: expected a positive finite time step of at most " << kMaxTimeStep << " s, got " << dt;
    throw std::invalid_argument(os.str());
  }
}

}  // namespace

// ---------------------------------------------------------------- Engine
int Engine::default_threads() {
  const unsigned n = std::thread::hardware_concurrency();
  return n > 0 ? static_cast<int>(n) : 1;
}

Engine::Engine(const Model& model, int threads, const std::string& dtype) {
  if (threads <= 0 || threads > 1024) {
    std::ostringstream os;
    os << "threads: expected a thread count in 1..1024, got " << threads;
    throw std::invalid_argument(os.str());
  }
  if (dtype == "float64") impl_.reset(new EngineT<double>(model, threads, dtype));
  else if (dtype == "float32") impl_.reset(new EngineT<float>(model, threads, dtype));
  else throw std::invalid_argument("dtype: expected 'float64' or 'float32', got '" + dtype + "'");
}
Engine::~Engine() = default;

int Engine::threads() const { return impl_->threads; }
const std::string& Engine::dtype() const { return impl_->dtype; }
int Engine::simd_width() const { return impl_->W; }
const Model& Engine::model() const { return impl_->model; }
unsigned long Engine::workspace_bytes() const { return impl_->workspace_bytes(); }
void Engine::set_max_job_packs(long packs) {
  if (packs < 1 || packs > Pool::kMaxUnits) {
    std::ostringstream os;
    os << "set_max_job_packs: packs: expected 1.." << Pool::kMaxUnits << ", got " << packs;
    throw std::invalid_argument(os.str());
  }
  std::lock_guard<std::mutex> lk(impl_->call);
  impl_->max_job_packs = packs;
}

// ---- the typed entry points: registered operations (ops/registry.hpp)
namespace {
template <typename T> struct Call : ops::OpCall {
  explicit Call(long b) { B = b; }
  Call& input(int k, const T* p) { in[k] = p, batched[k] = true; return *this; }
  Call& output(int k, T* p) { out[k] = p; return *this; }
};
template <typename Op> constexpr int id_of() { return ops::index_of<Op>(ops::AllOps{}); }
}  // namespace

template <typename T>
void Engine::inverse_dynamics(long B, const T* q, const T* qd, const T* qdd, T gravity, T* tau) {
  impl_as<T>(impl_.get(), "inverse_dynamics");  // the engine's dtype only
  Call<T> c(B);
  c.input(0, q).input(1, qd).input(2, qdd).output(0, tau).real[3] = gravity;
  run_op(id_of<ops::InverseDynamics>(), c);
}

template <typename T> void Engine::crba(long B, const T* q, T* M) {
  impl_as<T>(impl_.get(), "crba");  // the engine's dtype only
  run_op(id_of<ops::Crba>(), Call<T>(B).input(0, q).output(0, M));
}

template <typename T> void Engine::minv(long B, const T* q, T* Minv) {
  impl_as<T>(impl_.get(), "minv");  // the engine's dtype only
  Call<T> c(B);
  c.input(0, q).output(0, Minv).choice[1] = 1;  // dense
  run_op(id_of<ops::Minv>(), c);
}

template <typename T>
void Engine::forward_dynamics(long B, const T* q, const T* qd, const T* tau, T gravity, T* qdd) {
  impl_as<T>(impl_.get(), "forward_dynamics");  // the engine's dtype only
  Call<T> c(B);
  c.input(0, q).input(1, qd).input(2, tau).output(0, qdd).real[4] = gravity;
  run_op(id_of<ops::Aba>(), c);
}

template <typename T>
void Engine::inverse_dynamics_gradient(long B, const T* q, const T* qd, const T* qdd, T gravity, T* dtau_dq,
                                       T* dtau_dqd) {
  impl_as<T>(impl_.get(), "inverse_dynamics_gradient");  // the engine's dtype only
  Call<T> c(B);
  c.input(0, q).input(1, qd).input(2, qdd).output(1, dtau_dq).output(2, dtau_dqd).real[3] = gravity;
  run_op(id_of<ops::InverseDynamicsGradient>(), c);
}

template <typename T>
void Engine::forward_dynamics_gradient(long B, const T* q, const T* qd, const T* tau, T gravity, T* dqdd_dq,
                                       T* dqdd_dqd, T* Minv) {
  impl_as<T>(impl_.get(), "forward_dynamics_gradient");  // the engine's dtype only
  Call<T> c(B);
  c.input(0, q).input(1, qd).input(2, tau).output(0, dqdd_dq).output(1, dqdd_dqd).output(3, Minv).real[4] = gravity;
  run_op(id_of<ops::ForwardDynamicsGradient>(), c);
}

template <typename T>
void Engine::integrator(long B, const T* q, const T* qd, const T* u, T dt, T gravity, int type, T* x) {
  impl_as<T>(impl_.get(), "integrator");  // the engine's dtype only
  check_type("integrator", type);
  check_dt("integrator", dt);
  Call<T> c(B);
  c.input(0, q).input(1, qd).input(2, u).output(0, x);
  c.real[3] = dt, c.choice[4] = type, c.real[6] = gravity;
  run_op(id_of<ops::Integrator>(), c);
}

template <typename T>
void Engine::integrator_gradient(long B, const T* q, const T* qd, const T* u, T dt, T gravity, int type, T* x,
                                 T* AB) {
  impl_as<T>(impl_.get(), "integrator_gradient");  // the engine's dtype only
  check_type("integrator_gradient", type);
  check_dt("integrator_gradient", dt);
  Call<T> c(B);
  c.input(0, q).input(1, qd).input(2, u).output(0, x).output(1, AB);
  c.real[3] = dt, c.choice[4] = type, c.real[6] = gravity;
  run_op(id_of<ops::IntegratorGradient>(), c);
}

void Engine::run_op(int op, const ops::OpCall& call) {
  if (op < 0 || op >= ops::AllOps::size) throw std::invalid_argument("run_op: unknown operation id " + std::to_string(op));
  const char* what = ops::op_table()[op].spec->name;
  if (call.B <= 0) {
    std::ostringstream os;
    os << what << ": B: expected a positive batch size, got " << call.B;
    throw std::invalid_argument(os.str());
  }
  if (impl_->dtype == "float64") routes<double>()[op](impl_as<double>(impl_.get(), what), call);
  else routes<float>()[op](impl_as<float>(impl_.get(), what), call);
}


#define RBD_ENGINE_INSTANTIATE(T)                                                                              \
  template void Engine::inverse_dynamics<T>(long, const T*, const T*, const T*, T, T*);                       \
  template void Engine::crba<T>(long, const T*, T*);                                                          \
  template void Engine::minv<T>(long, const T*, T*);                                                          \
  template void Engine::forward_dynamics<T>(long, const T*, const T*, const T*, T, T*);                       \
  template void Engine::inverse_dynamics_gradient<T>(long, const T*, const T*, const T*, T, T*, T*);          \
  template void Engine::forward_dynamics_gradient<T>(long, const T*, const T*, const T*, T, T*, T*, T*);      \
  template void Engine::integrator<T>(long, const T*, const T*, const T*, T, T, int, T*);                     \
  template void Engine::integrator_gradient<T>(long, const T*, const T*, const T*, T, T, int, T*, T*);
RBD_ENGINE_INSTANTIATE(double)
RBD_ENGINE_INSTANTIATE(float)
#undef RBD_ENGINE_INSTANTIATE

}  // namespace rbd

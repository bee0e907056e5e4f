// The registry at run time (ops/table.hpp): the table generated from
// ops::AllOps, the checks of a call, and the serial per-sample loop.
#include "rbdkit/ops/table.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "rbdkit/batch/dynamics.hpp"
#include "rbdkit/batch/kinematics_api.hpp"
#include "rbdkit/batch/mujoco_api.hpp"
#include "rbdkit/ops/registry.hpp"

namespace rbd {
namespace ops {

namespace {

template <typename Op> bool kernel64(const ModelView<double>& m, Workspace<double>& w, const OpArgs<double>& a) {
  return Op::run(m, w, a);
}

template <typename... Op> std::vector<OpEntry> make_table(OpList<Op...>) {
  std::vector<OpEntry> t;
  int id = 0;
  ((t.push_back({id++, &Op::spec, &kernel64<Op>})), ...);
  return t;
}

std::string label_of(const char* name, bool batched, long s) {
  return batched ? std::string(name) + "[" + std::to_string(s) + "]" : std::string(name);
}

template <typename T> struct Bounds;
template <> struct Bounds<double> {
  static constexpr double input = kMaxInput, angle = kMaxAngle;
};
template <> struct Bounds<float> {
  static constexpr double input = kMaxInputF32, angle = kMaxAngleF32;
};

// n finite values of magnitude at most Bounds<T>::input
template <typename T> bool finite_values(const T* x, long n) { return within_bound(x, n, Bounds<T>::input); }

template <typename T> [[noreturn]] void throw_values(const T* x, long n, const std::string& label) {
  for (long k = 0; k < n; ++k) {
    const double v = static_cast<double>(x[k]);
    std::ostringstream os;
    if (!std::isfinite(v)) {
      os << label << ": expected finite values, got " << v << " at flat index " << k;
      throw std::invalid_argument(os.str());
    }
    if (std::fabs(v) > Bounds<T>::input) {
      os << label << ": expected values of magnitude at most " << Bounds<T>::input
         << " (larger ones overflow), got " << v << " at flat index " << k;
      throw std::invalid_argument(os.str());
    }
  }
  throw std::logic_error("throw_values: no bad value");
}

// a configuration (nq values) in a convention: finite, bounded angles, unit quaternions
template <typename T> void check_configuration_values(const Model& m, const T* q, const char* name, bool batched,
                                                      long s, int convention) {
  const bool ok = configuration_within_bounds(m.bodies.data(), m.nb(), m.nq, q, Bounds<T>::input, Bounds<T>::angle);
  if (ok) return;
  // the message: the bounds of T first, then the float64 checks (joint angles, quaternions)
  const std::string label = label_of(name, batched, s);
  if (!finite_values(q, m.nq)) throw_values(q, m.nq, label);
  std::vector<double> qd(static_cast<size_t>(m.nq));  // (sized first: nq >= 0, as the compiler cannot see)
  std::copy(q, q + qd.size(), qd.begin());
  for (size_t i = 0; i < m.bodies.size(); ++i) {
    const BodyDesc<double>& b = m.bodies[i];
    if (!b.mimic && (b.type == kRevolute || b.type == kHelical) && std::fabs(qd[b.q_idx]) > Bounds<T>::angle) {
      std::ostringstream os;
      os << label << ": the angle of joint '" << m.joints[i].name << "' (q[" << b.q_idx << "]) must have magnitude "
         << "at most " << Bounds<T>::angle << " rad (beyond it sin and cos have no precision left), got " << qd[b.q_idx];
      throw std::invalid_argument(os.str());
    }
  }
  check_configuration_in(m, qd.data(), name, batched ? s : -1, convention);
  throw std::logic_error("check_configuration_values: no bad value");
}

// bounds lo < hi entry by entry, each finite (at most Bounds<T>::input) or infinite on its side
template <typename T> void check_bounds(const T* lo, bool lo_batched, const T* hi, bool hi_batched, long n, long B,
                                        const char* lo_name, const char* hi_name) {
  const long samples = lo_batched || hi_batched ? B : 1;
  // finite values within the bound, each bound by itself
  for (int side = 0; side < 2; ++side) {
    const T* x = side ? hi : lo;
    const long m = (side ? hi_batched : lo_batched) ? B : 1;
    for (long s = 0; s < m; ++s)
      for (long j = 0; j < n; ++j) {
        const double v = x[s * n + j];
        if (!std::isfinite(v) || std::fabs(v) <= Bounds<T>::input) continue;
        std::ostringstream os;
        os << label_of(side ? hi_name : lo_name, side ? hi_batched : lo_batched, s) << ": expected values of magnitude at most "
           << Bounds<T>::input << " (larger ones overflow; an infinite bound is no bound), got " << v
           << " at flat index " << j;
        throw std::invalid_argument(os.str());
      }
  }
  // then as a pair: not NaN, infinite only on their side, lower < upper
  for (long s = 0; s < samples; ++s)
    for (long j = 0; j < n; ++j) {
      const double l = lo[(lo_batched ? s * n : 0) + j], h = hi[(hi_batched ? s * n : 0) + j];
      if (l < h && l != INFINITY && h != -INFINITY) continue;
      std::ostringstream os;
      os << lo_name << ", " << hi_name << ": expected " << lo_name << " < " << hi_name << " (infinite bounds allowed: "
         << "-inf below, +inf above), got " << l << " and " << h << " at ";
      if (samples > 1) os << "sample " << s << ", ";
      os << "flat index " << j;
      throw std::invalid_argument(os.str());
    }
}

[[noreturn]] void bad_param(const ArgSpec& a, const std::string& what) {
  throw std::invalid_argument(std::string(a.name) + ": " + what);
}

int n_choices(const ArgSpec& a) {
  int n = 0;
  while (a.choices && a.choices[n]) ++n;
  return n;
}

}  // namespace

void check_bounded(const double* x, long samples, long n, const char* name, bool batched, double bound,
                   bool non_finite_ok) {
  for (long s = 0; s < samples; ++s)
    for (long k = 0; k < n; ++k) {
      const double v = x[s * n + k];
      if (std::fabs(v) <= bound || (non_finite_ok && !std::isfinite(v))) continue;
      std::ostringstream os;
      os << label_of(name, batched, s) << ": expected ";
      if (std::isfinite(v)) os << "values of magnitude at most " << bound << " (larger ones overflow), got " << v;
      else os << "finite values, got " << v;
      os << " at flat index " << k;
      throw std::invalid_argument(os.str());
    }
}

const std::vector<OpEntry>& op_table() {
  static const std::vector<OpEntry> table = make_table(AllOps{});
  return table;
}

int find_op(const std::string& name) {
  for (const OpEntry& e : op_table())
    if (name == e.spec->name) return e.id;
  return -1;
}

long arg_values(const ArgSpec& a, const Model& m, int n_ee) { return values_of(a.shape, m.nq, m.nv, m.nb(), n_ee); }
long out_values(const OutSpec& o, const Model& m, int n_ee) { return values_of(o.shape, m.nq, m.nv, m.nb(), n_ee); }

long scratch_values(const OpSpec& op, const Model& m) {
  switch (op.scratch) {
    case kNoScratch: return 0;
    case kScratchNv: return m.nv;
    case kScratch6Nv: return 6L * m.nv;
    case kScratch2NvNv: return 2L * m.nv * m.nv;
    case kScratchIntegrator: return integrator_scratch_values(m.nq, m.nv);
    case kScratchIntegratorGrad: return integrator_gradient_scratch_values(m.nq, m.nv) + m.nq + m.nv;
    case kScratchNvNv: return static_cast<long>(m.nv) * m.nv;
    case kScratchDccrbaFd: return dccrba_fd_scratch(m.nq, m.nv);
    case kScratchCmmFd: return 6L * m.nv * m.nv + dccrba_fd_scratch(m.nq, m.nv);
    case kScratchComCost: return com_cost_scratch(m.nq, m.nv);
    case kScratchMomentumCost: return momentum_cost_scratch(m.nq, m.nv);
    case kScratchEePosCost: return ee_pos_cost_scratch(m.nq, m.nv);
    case kScratchD2Integrate: return 2L * (2 * m.nq + 2 * m.nv + static_cast<long>(m.nv) * m.nv);
    case kScratchEeHessianDual: return ee_hessian_dual_scratch(m.nb(), m.nq, m.nv);
    case kScratchIntegratorFExtGrad:
      return integrator_fext_gradient_scratch_values(m.nq, m.nv, m.nb()) + m.nq + m.nv + 6L * m.nv * m.nv;
    case kScratchIntegratorHessian:
      return integrator_hessian_scratch_values(m.nq, m.nv) + m.nq + m.nv + 6L * m.nv * m.nv;
  }
  return 0;
}

WorkspaceLayout workspace_layout(const OpSpec& op, const Model& m) {
  if (op.workspace == kLinear) return kLinearWorkspace;
  if (op.workspace == kLinearUnlessMimic) return aba_layout(m);
  return kFullWorkspace;
}

int call_convention(const OpSpec& op, const OpCall& c) {
  for (int k = 0; k < op.n_args; ++k)
    if (op.args[k].kind == kConvention) return c.choice[k];
  return kPinocchioConvention;
}

template <typename T> void check_call(const Model& m, const OpSpec& op, const OpCall& c, bool values) {
  if (op.model == kNoMimic && m.has_mimic())
    throw std::invalid_argument(std::string(op.name) + ": this operation applies to models without mimic joints; "
                                "this model has mimic joints");
  if (op.model == kNoMimic && m.general_path())
    throw std::invalid_argument(std::string(op.name) + ": this operation needs each subtree's coordinates "
                                "contiguous (bodies added depth-first); this model's are not");
  // parameters first (cheap), then the arrays in argument order
  for (int k = 0; k < op.n_args; ++k) {
    const ArgSpec& a = op.args[k];
    switch (a.kind) {
      case kArray:
        if (!c.in[k]) bad_param(a, "expected an array, got nothing (null)");
        break;
      case kOptionalArray: break;
      case kReal:
        if (!(std::fabs(c.real[k]) <= Bounds<T>::input)) {
          std::ostringstream os;
          if (std::isfinite(c.real[k]))
            os << "expected a magnitude of at most " << Bounds<T>::input << " (larger ones overflow), got " << c.real[k];
          else
            os << "expected a finite number, got " << c.real[k];
          bad_param(a, os.str());
        }
        break;
      case kTimeStep: check_time_step(c.real[k], a.name); break;
      case kPositive:
        if (!(c.real[k] > 0 && static_cast<T>(c.real[k]) > 0 && c.real[k] <= Bounds<T>::input)) {
          std::ostringstream os;
          if (!std::isfinite(c.real[k])) os << "expected a finite number, got " << c.real[k];
          else if (c.real[k] > Bounds<T>::input)
            os << "expected a magnitude of at most " << Bounds<T>::input << ", got " << c.real[k];
          else if (c.real[k] > 0)  // rounds to 0 in float32
            os << "expected a positive " << (a.choices ? a.choices[0] : "number") << " of at least "
               << std::numeric_limits<T>::denorm_min() << " (the handle's dtype rounds it to 0), got " << c.real[k];
          else os << "expected a positive " << (a.choices ? a.choices[0] : "number") << ", got " << c.real[k];
          bad_param(a, os.str());
        }
        break;
      case kFlag:
        if (c.choice[k] != 0 && c.choice[k] != 1) bad_param(a, "expected 0 or 1, got " + std::to_string(c.choice[k]));
        break;
      case kChoice:
        if (c.choice[k] < 0 || c.choice[k] >= n_choices(a))
          bad_param(a, "expected a choice index in 0.." + std::to_string(n_choices(a) - 1) + ", got " +
                           std::to_string(c.choice[k]));
        break;
      case kIntegrator:
        if (c.choice[k] < kEuler || c.choice[k] > kConstantAcceleration)
          bad_param(a, "expected 0..5 (euler, semi_implicit_euler, midpoint, rk4, trapezoidal, "
                       "constant_acceleration), got " + std::to_string(c.choice[k]));
        break;
      case kConvention: check_convention(c.choice[k]); break;
      case kFrame:
        if (m.frames.empty()) bad_param(a, "the model has no frames");
        if (c.choice[k] < 0 || c.choice[k] >= static_cast<int>(m.frames.size()))
          bad_param(a, "expected a frame index in 0.." + std::to_string(m.frames.size() - 1) + ", got " +
                           std::to_string(c.choice[k]));
        break;
      case kEndEffectors:
        if (c.n_ee < 1 || !c.ee) bad_param(a, "expected at least one end effector, got none");
        for (int e = 0; e < c.n_ee; ++e)
          if (c.ee[e] < 0 || c.ee[e] >= m.nb())
            bad_param(a, "body index " + std::to_string(c.ee[e]) + " out of range [0, " + std::to_string(m.nb()) +
                             ")");
        break;
      case kEndEffector:
        if (c.choice[k] < -1 || c.choice[k] >= m.nb())
          bad_param(a, "expected a body index in 0.." + std::to_string(m.nb() - 1) + " (-1: the first leaf body), got " +
                           std::to_string(c.choice[k]));
        if (c.choice[k] == -1 && m.nb() == 0)
          bad_param(a, "the model has no joints (nq = 0), so it has no end effector");
        break;
    }
  }
  // the outputs every caller asks for: the kernels write them unconditionally
  const unsigned needed = required_outputs(op);
  for (int o = 0; o < op.n_out; ++o)
    if ((needed >> o & 1u) && !c.out[o])
      throw std::invalid_argument(std::string(op.name) + ": output " + op.out[o].name +
                                  ": expected an array, got nothing (null)");
  if (!values) return;
  const int convention = call_convention(op, c);
  for (int k = 0; k < op.n_args; ++k) {
    const ArgSpec& a = op.args[k];
    if ((a.kind != kArray && a.kind != kOptionalArray) || !c.in[k]) continue;
    const T* x = static_cast<const T*>(c.in[k]);
    const long n = arg_values(a, m, c.n_ee), samples = c.batched[k] ? c.B : 1;
    if (a.check == kFiniteValues || a.check == kWeights) {
      if (!finite_values(x, n * samples))
        for (long s = 0; s < samples; ++s)
          if (!finite_values(x + s * n, n)) throw_values(x + s * n, n, label_of(a.name, c.batched[k], s));
      if (a.check == kWeights)
        for (long s = 0; s < samples; ++s)
          for (long j = 0; j < n; ++j)
            if (x[s * n + j] < 0) {
              std::ostringstream os;
              os << label_of(a.name, c.batched[k], s) << ": expected non-negative weights, got " << x[s * n + j]
                 << " at flat index " << j;
              throw std::invalid_argument(os.str());
            }
      continue;
    }
    if (a.check == kLowerBound) continue;  // with its upper bound, the argument after it
    if (a.check == kUpperBound) {
      check_bounds(static_cast<const T*>(c.in[k - 1]), c.batched[k - 1], x, c.batched[k], n, c.B,
                   op.args[k - 1].name, a.name);
      continue;
    }
    // a configuration, or a state [q; qd] whose first nq values are one
    for (long s = 0; s < samples; ++s) {
      check_configuration_values(m, x + s * n, a.name, c.batched[k], s,
                                 a.check == kMujocoConfiguration ? kMujocoConvention : convention);
      if (n > m.nq && !finite_values(x + s * n, n)) throw_values(x + s * n, n, label_of(a.name, c.batched[k], s));
    }
  }
}
template void check_call<double>(const Model&, const OpSpec&, const OpCall&, bool);
template void check_call<float>(const Model&, const OpSpec&, const OpCall&, bool);

bool takes_names(const OpSpec& op) {
  for (int k = 0; k < op.n_args; ++k)
    if (op.args[k].kind == kFrame || op.args[k].kind == kEndEffector) return true;
  return false;
}

template <typename T> OpCall resolve_names(const Model& m, const OpSpec& op, const OpCall& c, std::vector<T>& frames) {
  OpCall r = c;
  frames.assign(12 * op.n_args, T(0));
  for (int k = 0; k < op.n_args; ++k) {
    if (op.args[k].kind == kEndEffector && c.choice[k] == -1) r.choice[k] = leaf_bodies(m).front();
    if (op.args[k].kind != kFrame) continue;
    const FrameInfo& f = m.frames[c.choice[k]];
    T* x = frames.data() + 12 * k;
    for (int j = 0; j < 9; ++j) x[j] = static_cast<T>(f.X_body_frame.R.m[j]);
    x[9] = static_cast<T>(f.X_body_frame.p.x), x[10] = static_cast<T>(f.X_body_frame.p.y);
    x[11] = static_cast<T>(f.X_body_frame.p.z);
    r.choice[k] = f.body;
    r.in[k] = x;
    r.batched[k] = false;
  }
  return r;
}
template OpCall resolve_names<double>(const Model&, const OpSpec&, const OpCall&, std::vector<double>&);
template OpCall resolve_names<float>(const Model&, const OpSpec&, const OpCall&, std::vector<float>&);

void throw_failure(const Model& m, const OpSpec& op, const double* q, long sample, const OpCall* call) {
  if (op.failure == kNoMass) {
    std::ostringstream os;
    os << op.name << ": the robot has no mass (total mass 0";
    if (sample >= 0) os << " at sample " << sample;
    os << "), so its centre of mass is undefined";
    throw std::runtime_error(os.str());
  }
  if (op.failure == kNotPositiveDefinite || singular_joint(m, q) >= 0)
    throw_not_positive_definite(m, op.name, q, sample);
  if (op.failure == kOscSingular) {
    // the first end effector that fewer than 6 DoF reach, else a singular configuration
    int which = -1, dof = 0;
    for (int e = 0; call && e < call->n_ee && which < 0; ++e) {
      std::vector<char> moves(m.nv, 0);  // coordinates that move the point (mimics share their target's)
      for (int k = call->ee[e]; k >= 0; k = m.bodies[k].parent)
        for (int a = 0; a < m.bodies[k].nv; ++a) moves[m.bodies[k].v_idx + a] = 1;
      dof = 0;
      for (char c : moves) dof += c;
      if (dof < 6) which = e;
    }
    std::ostringstream os;
    os << op.name << ": J M⁻¹ Jᵀ of ";
    if (which >= 0) os << "end effector " << which << " (joint '" << m.joints[call->ee[which]].name << "')";
    else os << "an end effector";
    os << " is singular";
    if (sample >= 0) os << " at sample " << sample;
    os << ": "
       << (which >= 0 ? "only " + std::to_string(dof) + " DoF reach it (6 are needed)"
                      : std::string("the configuration is singular (its Jacobian has rank < 6)"))
       << ", so the operational-space inertia is undefined";
    throw std::invalid_argument(os.str());
  }
  std::ostringstream os;
  os << op.name << ": a stage of the step overflowed (non-finite state or mass matrix)";
  if (sample >= 0) os << " at sample " << sample;
  os << "; reduce dt or the magnitudes of qd and u";
  throw std::runtime_error(os.str());
}

template <typename T> void check_outputs(const Model& m, const OpSpec& op, const OpCall& c) {
  if (op.outputs == kInfiniteOutside) return;
  for (int o = 0; o < op.n_out; ++o) {
    if (!c.out[o]) continue;
    const T* x = static_cast<const T*>(c.out[o]);
    const long n = c.B * out_values(op.out[o], m, c.n_ee);
    bool ok = true;
    for (long k = 0; k < n; ++k) ok &= std::isfinite(x[k]);
    if (ok) continue;
    for (long k = 0; k < n; ++k)
      if (!std::isfinite(x[k])) {
        std::ostringstream os;
        os << op.name << ": the result " << op.out[o].name << " is not finite (" << x[k] << " at flat index " << k
           << "): the computation overflowed; reduce the inputs' magnitudes (or dt)";
        throw std::runtime_error(os.str());
      }
  }
}
template void check_outputs<double>(const Model&, const OpSpec&, const OpCall&);
template void check_outputs<float>(const Model&, const OpSpec&, const OpCall&);

void run_serial(const Model& m, const OpEntry& e, const OpCall& c, Workspace<double>& w, double* scratch) {
  const OpSpec& op = *e.spec;
  const ModelView<double> mv = m.view();
  long in_step[kMaxArgs], out_step[kMaxOutputs];
  OpArgs<double> a;
  for (int k = 0; k < op.n_args; ++k) {
    a.in[k] = static_cast<const double*>(c.in[k]);
    a.real[k] = c.real[k];
    a.choice[k] = c.choice[k];
    in_step[k] = c.in[k] && c.batched[k] ? arg_values(op.args[k], m, c.n_ee) : 0;
  }
  for (int o = 0; o < op.n_out; ++o) out_step[o] = out_values(op.out[o], m, c.n_ee);
  a.scratch = scratch;
  a.ee = c.ee;
  a.n_ee = c.n_ee;
  for (long s = 0; s < c.B; ++s) {
    for (int k = 0; k < op.n_args; ++k)
      if (c.in[k]) a.in[k] = static_cast<const double*>(c.in[k]) + s * in_step[k];
    for (int o = 0; o < op.n_out; ++o) a.out[o] = c.out[o] ? static_cast<double*>(c.out[o]) + s * out_step[o] : nullptr;
    if (!e.run(mv, w, a)) throw_failure(m, op, a.in[0], c.B > 1 ? s : -1, &c);
  }
  check_outputs<double>(m, op, c);
}

}  // namespace ops
}  // namespace rbd

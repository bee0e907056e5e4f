// rbdkit/batch/dynamics.hpp — the host API: checked, batched entry points over raw
// row-major arrays (what the Python package calls), and the Dynamics class,
// an Eigen front end for one sample at a time. Host only.
//
// Every batched function takes B samples stacked on the leading axis:
//   q (B x nq), qd / qdd / tau (B x nv), f_ext (B x nb x 6, body frames,
//   [linear; angular]), and writes outputs of the documented shapes. Inputs
//   are checked first (finite values, unit quaternions); a bad one throws
//   std::invalid_argument naming the argument, the sample and the joint.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "rbdkit/algorithms/aba.hpp"
#include "rbdkit/algorithms/crba.hpp"
#include "rbdkit/algorithms/minv.hpp"
#include "rbdkit/algorithms/rnea.hpp"
#include "rbdkit/model/configuration.hpp"
#include "rbdkit/model/input_bounds.hpp"
#include "rbdkit/model/workspace.hpp"
#include "rbdkit/parsers/model.hpp"

namespace rbd {

// a workspace in scalar S with its own storage (one per thread), 16-byte
// aligned; the linear layout is not zero-filled (workspace.hpp), so
// untouched pages cost nothing
template <typename S> class WorkspaceBufferT {
 public:
  explicit WorkspaceBufferT(const Model& m, WorkspaceLayout layout = kFullWorkspace)
      : storage_(allocate(workspace_bytes<S>(m.nb(), m.nv, layout) + 16, layout)), layout_(layout) {
    unsigned char* p = storage_.get();
    const auto addr = reinterpret_cast<std::uintptr_t>(p);
    if (addr % 16) p += 16 - addr % 16;
    ws_ = carve_workspace<S>(p, m.nb(), m.nv, layout);
  }
  Workspace<S>& get() { return ws_; }
  WorkspaceLayout layout() const { return layout_; }

 private:
  // the full layout zero-filled, as it always was (O(nb·nv + nv²) like the
  // operations that use it); the linear one not: the O(n) family writes
  // every array before reading it (tests/cpp/test_workspace.cpp poisons it)
  static unsigned char* allocate(unsigned long bytes, WorkspaceLayout layout) {
    return layout == kFullWorkspace ? new unsigned char[bytes]() : new unsigned char[bytes];
  }

  std::unique_ptr<unsigned char[]> storage_;
  WorkspaceLayout layout_;
  Workspace<S> ws_;
};
using WorkspaceBuffer = WorkspaceBufferT<double>;

// the layout aba needs: linear, full on the general path (Model::general_path: its dense path) and
// where M's factorisation pays (minv_factored_pays: aba_factored)
inline WorkspaceLayout aba_layout(const Model& m) {
  return m.general_path() || minv_factored_pays(m.view()) ? kFullWorkspace : kLinearWorkspace;
}

// the caller's workspace, or one of our own of the given layout for the
// duration of a call (a caller's workspace must hold that layout)
class ScopedWorkspace {
 public:
  ScopedWorkspace(const Model& m, Workspace<double>* given, WorkspaceLayout layout = kFullWorkspace) : w_(given) {
    if (!w_) {
      own_.reset(new WorkspaceBuffer(m, layout));
      w_ = &own_->get();
    }
  }
  Workspace<double>& get() { return *w_; }

 private:
  std::unique_ptr<WorkspaceBuffer> own_;
  Workspace<double>* w_;
};

// a held workspace that grows with need (one per thread): linear until a
// call asks for the full layout, full from then on. What Dynamics and Handle
// keep, so that a model of many links pays for the quadratic arrays only
// once an O(n²) algorithm runs on it.
class WorkspaceCache {
 public:
  Workspace<double>& get(const Model& m, WorkspaceLayout layout) {
    if (!buf_ || (layout == kFullWorkspace && buf_->layout() != kFullWorkspace)) {
      buf_.reset();  // the old one goes first: the peak is one workspace
      buf_.reset(new WorkspaceBuffer(m, layout));
    }
    return buf_->get();
  }

 private:
  std::unique_ptr<WorkspaceBuffer> buf_;
};

// ---- input checks (throw std::invalid_argument)
// Bounds on inputs: kMaxInput, kMaxAngle, kMaxTimeStep and their float32
// counterparts (model/input_bounds.hpp).
// finite values of magnitude at most kMaxInput
void check_finite(const double* x, long n, const char* arg);
// finite values (kMaxInput, kMaxAngle for the angles of revolute and helical
// joints) and a unit quaternion (|‖quat‖ - 1| <= 1e-6) for every free-flyer
// and spherical joint; `sample` only labels the message (-1: none)
void check_configuration(const Model& m, const double* q, const char* arg, long sample = -1);
// |angle| <= kMaxAngle for the revolute and helical joints of q (nq)
void check_joint_angles(const Model& m, const double* q, const char* label);
// 0 < dt <= kMaxTimeStep
void check_time_step(double dt, const char* arg = "dt");
// the outputs of an operation (n values) are finite: std::runtime_error naming
// `what` and `out` otherwise (an overflow that the input bounds let through)
void check_result(const double* x, long n, const char* what, const char* out);
// the same for B stacked configurations (B x nq)
void check_configurations(const Model& m, long B, const double* q, const char* arg);

// ---- a mass matrix that is not positive definite: std::runtime_error
// "<what>: joint '<name>' moves no mass at sample <s>: the mass matrix is
// singular (...)", naming the joint whose articulated inertia is singular at
// q (nq, the sample's configuration; aba_singular_body), or the general
// message when none is (e.g. a singularity through mimic couplings).
// sample -1: one sample, not labelled.
[[noreturn]] void throw_not_positive_definite(const Model& m, const char* what, const double* q, long sample);
// the index of the joint (= body) whose articulated inertia is singular at q, or -1
int singular_joint(const Model& m, const double* q);

// The dynamics functions take an optional workspace (made with
// WorkspaceBuffer for the same model); without one they allocate their own
// once per call. inverse_dynamics needs the linear layout, aba aba_layout(m),
// the others the full one.
namespace batch {
// tau (B x nv); per-body v, a (without gravity), f (joint force) (B x nb x 6) when not null
void inverse_dynamics(const Model& m, long B, const double* q, const double* qd, const double* qdd,
                      const double* fext, double gravity, double* tau, double* v, double* a, double* f,
                      Workspace<double>* ws = nullptr);
// M (B x nv x nv)
void crba(const Model& m, long B, const double* q, double* M, Workspace<double>* ws = nullptr);
// Minv (B x nv x nv); upper triangle only when dense is false
void minv(const Model& m, long B, const double* q, bool dense, double* Minv, Workspace<double>* ws = nullptr);
// qdd (B x nv) by aba (the articulated-body algorithm, or M's factorisation on a small tree)
void aba(const Model& m, long B, const double* q, const double* qd, const double* tau, const double* fext,
         double gravity, double* qdd, Workspace<double>* ws = nullptr);
// qdd (B x nv) = M⁻¹ (tau - c)
void forward_dynamics(const Model& m, long B, const double* q, const double* qd, const double* tau,
                      const double* fext, double gravity, double* qdd, Workspace<double>* ws = nullptr);
// q_next (B x nq)
void integrate(const Model& m, long B, const double* q, const double* v, double* out);
// v (B x nv)
void difference(const Model& m, long B, const double* q0, const double* q1, double* out);
// J (B x nv x nv); arg 0 = ∂/∂q, 1 = ∂/∂v
void dintegrate(const Model& m, long B, const double* q, const double* v, int arg, double* J);
// J (B x nv x nv); arg 0 = ∂/∂q0 ('from'), 1 = ∂/∂q1 ('to')
void ddifference(const Model& m, long B, const double* q0, const double* q1, int arg, double* J);
// H (B x nv x nv x nv): H[i][j][k] = ∂ dintegrate(q, v, arg1)[i][j] / ∂ x_k,
// x = arg2 (0: q through integrate(q, δ), 1: v)
void d2integrate(const Model& m, long B, const double* q, const double* v, int arg1, int arg2, double* H);
}  // namespace batch

// one sample at a time, Eigen in and out; holds its workspace, so one
// Dynamics per thread
class Dynamics {
 public:
  explicit Dynamics(Model model);
  const Model& model() const { return model_; }

  Eigen::VectorXd inverse_dynamics(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                   const Eigen::VectorXd& qdd, double gravity = -9.81,
                                   const Eigen::MatrixXd& fext = Eigen::MatrixXd());
  Eigen::MatrixXd crba(const Eigen::VectorXd& q);
  Eigen::MatrixXd minv(const Eigen::VectorXd& q, bool dense = true);
  Eigen::VectorXd aba(const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const Eigen::VectorXd& tau,
                      double gravity = -9.81, const Eigen::MatrixXd& fext = Eigen::MatrixXd());
  Eigen::VectorXd forward_dynamics(const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const Eigen::VectorXd& tau,
                                   double gravity = -9.81, const Eigen::MatrixXd& fext = Eigen::MatrixXd());
  Eigen::VectorXd nonlinear_effects(const Eigen::VectorXd& q, const Eigen::VectorXd& qd, double gravity = -9.81);
  Eigen::VectorXd generalized_gravity(const Eigen::VectorXd& q, double gravity = -9.81);
  Eigen::VectorXd integrate(const Eigen::VectorXd& q, const Eigen::VectorXd& v);
  Eigen::VectorXd difference(const Eigen::VectorXd& q0, const Eigen::VectorXd& q1);

  // unchecked fast paths on raw arrays for benchmarks and inner loops (a
  // full workspace)
  Workspace<double>& workspace() { return ws_.get(model_, kFullWorkspace); }
  ModelView<double> view() const { return model_.view(); }

 private:
  Model model_;
  WorkspaceCache ws_;
};

}  // namespace rbd

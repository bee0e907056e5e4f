// Host entry points of the second-order dynamics derivatives: input checks
// and the batched loops over algorithms/idsva_so.hpp and fdsva_so.hpp.
#include <sstream>
#include <stdexcept>

#include "rbdkit/algorithms/fdsva_so.hpp"
#include "rbdkit/batch/second_order_api.hpp"

namespace rbd {
namespace batch {

namespace {
void check_state(const Model& m, long B, const double* q, const double* qd, const double* x, const char* x_name,
                 double gravity) {
  check_configurations(m, B, q, "q");
  check_finite(qd, B * m.nv, "qd");
  check_finite(x, B * m.nv, x_name);
  check_finite(&gravity, 1, "gravity");
}
}  // namespace

void idsva_so(const Model& m, long B, const double* q, const double* qd, const double* qdd, double gravity,
              int frame, double* d2tau_dq2, double* d2tau_dqd2, double* d2tau_dqdqd, double* dM_dq,
              Workspace<double>* ws) {
  if (frame != kSoBodyFrame && frame != kSoWorldFrame && frame != kSoAuto)
    throw std::invalid_argument("frame: expected kSoBodyFrame, kSoWorldFrame or kSoAuto, got " + std::to_string(frame));
  check_state(m, B, q, qd, qdd, "qdd", gravity);
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  const long nv = m.nv, blk = nv * nv * nv;
  for (long s = 0; s < B; ++s) {
    const double *qs = q + s * m.nq, *vs = qd + s * nv, *as = qdd + s * nv;
    double *o1 = d2tau_dq2 + s * blk, *o2 = d2tau_dqd2 + s * blk, *o3 = d2tau_dqdqd + s * blk, *o4 = dM_dq + s * blk;
    if (frame == kSoBodyFrame)
      idsva_so_body_frame(mv, buf.get(), qs, vs, as, gravity, o1, o2, o3, o4);
    else if (frame == kSoWorldFrame)
      idsva_so_world_frame(mv, buf.get(), qs, vs, as, gravity, o1, o2, o3, o4);
    else
      rbd::idsva_so(mv, buf.get(), qs, vs, as, gravity, o1, o2, o3, o4);
  }
}

void fdsva_so(const Model& m, long B, const double* q, const double* qd, const double* u, double gravity,
              double* d2qdd_dq2, double* d2qdd_dqd2, double* d2qdd_dqdqd, double* d2qdd_dqdu, Workspace<double>* ws) {
  check_state(m, B, q, qd, u, "u", gravity);
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  const long nv = m.nv, blk = nv * nv * nv;
  for (long s = 0; s < B; ++s)
    if (!rbd::fdsva_so(mv, buf.get(), q + s * m.nq, qd + s * nv, u + s * nv, gravity, d2qdd_dq2 + s * blk,
                       d2qdd_dqd2 + s * blk, d2qdd_dqdqd + s * blk, d2qdd_dqdu + s * blk))
      throw_not_positive_definite(m, "fdsva_so", q + s * m.nq, B > 1 ? s : -1);
}

}  // namespace batch
}  // namespace rbd

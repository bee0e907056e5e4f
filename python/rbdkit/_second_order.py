"""Second-order dynamics derivatives on rbdkit.RBD (analytical IDSVA-SO
recursions and the FDSVA-SO relations, in the C++ core): idsva_so,
idsva_so_body_frame, idsva_so_world_frame and fdsva_so are registered
operations (include/rbdkit/ops/registry.hpp), bound by rbdkit.RBD itself;
this module documents their tensors.

Every tensor is (nv, nv, nv) (with a leading batch axis B when an argument
is batched), index order [i, j, k]:

  d2tau_dq2[i, j, k]   = ∂/∂q_k (∂tau_i/∂q_j)
  d2tau_dqd2[i, j, k]  = ∂²tau_i / ∂qd_j ∂qd_k          (symmetric in j, k)
  d2tau_dqdqd[i, j, k] = ∂²tau_i / ∂q_j ∂qd_k
  dM_dq[i, j, k]       = ∂M_ij / ∂q_k
  d2qdd_dq2, d2qdd_dqd2, d2qdd_dqdqd: the same for qdd = forward_dynamics(q, qd, u)
  d2qdd_dqdu[i, j, k]  = ∂²qdd_i / ∂q_j ∂u_k

q derivatives are tangent-space: ∂/∂q_k is the derivative along
q <- integrate(q, δ e_k), and ∂tau/∂q_j is inverse_dynamics_gradient's
column j, so d2tau_dq2[:, :, k] is what central differences of that gradient
along integrate give. It is symmetric in (j, k) except inside a free-flyer or
spherical joint, whose tangent directions do not commute: there
d2tau_dq2[i, j, k] - d2tau_dq2[i, k, j] = ∂tau_i/∂q · [e_k, e_j] (the Lie
bracket of the two directions); its symmetric part is the Hessian of
δ ↦ tau(integrate(q, δ)) at δ = 0.
"""

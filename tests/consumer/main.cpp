// Loads a robot through an installed rbdkit and checks M·M⁻¹ = I.
#include <Eigen/Dense>
#include <iostream>
#include <rbdkit/batch/dynamics.hpp>

int main(int argc, char** argv) {
  if (argc < 2) return 2;
  rbd::Dynamics d(rbd::Model::from_urdf_file(argv[1]));
  const Eigen::VectorXd q = Eigen::VectorXd::Constant(d.model().nq, 0.3);
  const double err = (d.crba(q) * d.minv(q) - Eigen::MatrixXd::Identity(d.model().nv, d.model().nv)).cwiseAbs().maxCoeff();
  std::cout << "nv=" << d.model().nv << " |M Minv - I| = " << err << "\n";
  return err < 1e-10 ? 0 : 1;
}

// Compiled instances of Eigen's dense decompositions (see linear_algebra.hpp).
#include "geometry/linear_algebra.hpp"

#include <Eigen/QR>
#include <Eigen/SVD>

namespace photomill::geometry {

Svd svd(const Eigen::MatrixXd& A, unsigned int vectors) {
  const Eigen::JacobiSVD<Eigen::MatrixXd> d(A, vectors);
  Svd out;
  out.singular_values = d.singularValues();
  if (d.computeU()) out.U = d.matrixU();
  if (d.computeV()) out.V = d.matrixV();
  return out;
}

Eigen::VectorXd singular_values(const Eigen::MatrixXd& A) { return svd(A).singular_values; }

Eigen::MatrixXd solve_least_norm(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B) {
  return A.completeOrthogonalDecomposition().solve(B);
}

Eigen::MatrixXd pseudo_inverse(const Eigen::MatrixXd& A) { return A.completeOrthogonalDecomposition().pseudoInverse(); }

}  // namespace photomill::geometry

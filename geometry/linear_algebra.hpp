// Dense decompositions that several stages use, compiled once: Eigen's JacobiSVD and complete
// orthogonal decomposition are header templates that cost GCC 15-20 s of compile in every
// translation unit naming them (measured: docs/measurements/walkthrough.md, 2026-12-04), so the
// stages call these functions instead of instantiating the templates themselves.
#pragma once

#include <Eigen/Core>

namespace photomill::geometry {

// A = U diag(s) V^T, s in decreasing order (Eigen's JacobiSVD: two-sided Jacobi rotations after a
// column-pivoting QR preconditioner, accurate to the unit roundoff relative to each singular
// value; Demmel & Veselic, "Jacobi's method is more accurate than QR", 1992). U and V are empty
// unless asked for.
struct Svd {
  Eigen::VectorXd singular_values;
  Eigen::MatrixXd U, V;
};

// Which singular vectors to compute: Eigen's DecompositionOptions (Eigen::ComputeFullU,
// ComputeThinU, ComputeFullV, ComputeThinV, combined with |); 0 for the singular values only.
Svd svd(const Eigen::MatrixXd& A, unsigned int vectors = 0);

// The singular values of A in decreasing order.
Eigen::VectorXd singular_values(const Eigen::MatrixXd& A);

// X minimising |A X - B| (Frobenius) with the least |X| among the minimisers: the complete
// orthogonal decomposition A P = Q [T 0; 0 0] Z (Golub & Van Loan, "Matrix computations", 4th
// ed., sec. 5.4.2), rank decided by Eigen's default threshold.
Eigen::MatrixXd solve_least_norm(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B);

// The Moore-Penrose pseudo-inverse of A, through the same decomposition.
Eigen::MatrixXd pseudo_inverse(const Eigen::MatrixXd& A);

}  // namespace photomill::geometry

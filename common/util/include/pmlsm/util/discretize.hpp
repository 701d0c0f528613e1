// Exact zero-order-hold discretisation of x' = A x + B u at period T:
//   Phi = e^{A T},  Gamma = int_0^T e^{A s} ds B,
// both read off one matrix exponential of the augmented matrix
//   exp([[A, B], [0, 0]] T) = [[Phi, Gamma], [0, I]]   (Van Loan, 1978).
#pragma once

#include <Eigen/Dense>

namespace pmlsm {

struct DiscreteModel {
  Eigen::MatrixXd phi;
  Eigen::MatrixXd gamma;
};

/// @throws std::invalid_argument on mismatched sizes, a non-finite entry or period_s <= 0.
DiscreteModel discretize_zoh(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, double period_s);

}  // namespace pmlsm

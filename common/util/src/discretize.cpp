#include "pmlsm/util/discretize.hpp"

#include <stdexcept>
#include <unsupported/Eigen/MatrixFunctions>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

DiscreteModel discretize_zoh(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, double period_s) {
  require_positive("period_s", period_s);
  const Eigen::Index n = a.rows();
  const Eigen::Index m = b.cols();
  if (a.cols() != n || b.rows() != n) {
    throw std::invalid_argument("discretize_zoh: A must be n x n and B n x m");
  }
  if (!a.allFinite() || !b.allFinite()) {
    throw std::invalid_argument("discretize_zoh: A and B must be finite");
  }
  Eigen::MatrixXd augmented = Eigen::MatrixXd::Zero(n + m, n + m);
  augmented.topLeftCorner(n, n) = a * period_s;
  augmented.topRightCorner(n, m) = b * period_s;
  const Eigen::MatrixXd e = augmented.exp();
  return DiscreteModel{e.topLeftCorner(n, n), e.topRightCorner(n, m)};
}

}  // namespace pmlsm

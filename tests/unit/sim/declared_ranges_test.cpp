// Each range is written once, in the component's declaration (pmlsm/util/parameter_table.hpp):
// a component's own validate() refuses every value its declaration refuses, naming the key as it
// stands in the component, though nothing but the declaration says the range.
#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>

#include "pmlsm/analysis/analysis_params.hpp"
#include "pmlsm/sim/system_params.hpp"
#include "test_support.hpp"

namespace pmlsm {
namespace {

// Walks a declaration and moves its `target`-th number (reals and whole numbers) just past its
// declared maximum; counts the numbers it passed.
class PastTheMaximum {
 public:
  explicit PastTheMaximum(std::size_t target) : target_(target) {}
  void real(const std::string& path, double& value, const Plausible& range) {
    if (index_++ == target_) {
      value = range.max + std::fabs(range.max) + 1.0;
      key_ = path.substr(1);
    }
  }
  template <typename T>
  void integer(const std::string& path, T& value, const Plausible& range) {
    // A whole number whose maximum is its type's own cannot be past it.
    if (index_++ == target_ && range.max < 1e15) {
      value = static_cast<T>(range.max + 1.0);
      key_ = path.substr(1);
    }
  }
  void flag(const std::string&, bool&) {}
  template <typename E, typename F>
  void choice(const std::string&, E&, F, const char* = nullptr) {}
  void vector3(const std::string& path, Eigen::Vector3d& value, const Plausible& range) {
    if (index_++ == target_) {
      value(1) = range.max * 2.0 + 1.0;
      key_ = path.substr(1) + "[1]";
    }
  }
  void integer_list(const std::string&, std::vector<int>&, const Plausible&) { ++index_; }

  std::size_t count() const { return index_; }
  const std::string& key() const { return key_; }

 private:
  std::size_t target_;
  std::size_t index_ = 0;
  std::string key_;
};

template <typename Params>
void declare_at_root(Params& p, PastTheMaximum& v) {
  if constexpr (table_detail::DeclaresLive<Params>::value) {
    Params::declare(std::string(), p, v, nullptr);
  } else {
    Params::declare(std::string(), p, v);
  }
}

/// Every number of `good`'s declaration, one at a time past its maximum: validate() refuses it
/// naming its key.
template <typename Params>
void expect_validate_refuses_each_declared_range(const Params& good, const char* name) {
  SCOPED_TRACE(name);
  ASSERT_NO_THROW(good.validate());
  PastTheMaximum counter(SIZE_MAX);
  Params copy = good;
  declare_at_root(copy, counter);
  ASSERT_GT(counter.count(), 0u);
  std::size_t checked = 0;
  for (std::size_t i = 0; i < counter.count(); ++i) {
    Params bad = good;
    PastTheMaximum past(i);
    declare_at_root(bad, past);
    if (past.key().empty()) continue;
    ++checked;
    try {
      bad.validate();
      ADD_FAILURE() << past.key() << " past its declared maximum was taken";
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()).rfind(past.key() + ":", 0), 0u) << e.what();
    }
  }
  EXPECT_GT(checked, 0u);
}

TEST(DeclaredRanges, EachComponentsValidateRefusesWhatItsDeclarationRefuses) {
  const SystemParams& s = test::shipped_params();
  expect_validate_refuses_each_declared_range(s.vibration_guard_params(), "vibration guard");
  expect_validate_refuses_each_declared_range(s.standstill_gate_params(), "standstill gate");
  expect_validate_refuses_each_declared_range(s.accel_feedback_params(), "acceleration feedback");
  expect_validate_refuses_each_declared_range(s.state_feedback_params(), "state feedback");
  expect_validate_refuses_each_declared_range(s.velocity_pi_params(), "velocity PI");
  expect_validate_refuses_each_declared_range(s.reference_model_params(), "reference model");
  expect_validate_refuses_each_declared_range(s.current_controller_params(), "current loop");
  expect_validate_refuses_each_declared_range(s.kalman_params(), "Kalman filter");
  expect_validate_refuses_each_declared_range(frequency_response_params(s), "frequency response");
  expect_validate_refuses_each_declared_range(tuning_targets(s), "tuning targets");
  expect_validate_refuses_each_declared_range(filter_design_params(s), "filter design");
  expect_validate_refuses_each_declared_range(s.plant.friction, "friction");
  expect_validate_refuses_each_declared_range(s.plant.ripple, "ripple");
}

}  // namespace
}  // namespace pmlsm

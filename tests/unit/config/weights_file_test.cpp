// The RNN weights file: round trips, the documented format, atomic saves, bad files named.
#include <gtest/gtest.h>

#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iterator>
#include <fstream>
#include <limits>
#include <new>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "pmlsm/compensation/jordan_rnn.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/config/weights_file.hpp"
#include "pmlsm/analysis/rnn_training.hpp"
#include "compensation/rnn_test_support.hpp"

namespace pmlsm {
namespace {

namespace fs = std::filesystem;
using namespace rnn_test;

class WeightsFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("pmlsm_rnn_test_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  static RnnWeightsFile sample() {
    RnnWeightsFile f;
    f.layer_sizes = {3, 6, 6, 3, 1};
    f.input_scale_s2_per_m = 0.02;
    f.gain_n = 300.0;
    f.cost = 5.3;
    f.source = "de_trainer seed 1 gen 433";
    f.weights = random_weights(91, 2.0, 21);
    return f;
  }

  // The sample file's text with one line replaced (or removed when with is empty).
  std::string write_variant(const std::string& name, const std::string& line_start, const std::string& with) {
    save_rnn_weights(path("base.yaml"), sample());
    std::ifstream in(path("base.yaml"));
    std::ostringstream out;
    std::string line;
    bool replaced = false;
    while (std::getline(in, line)) {
      if (!replaced && line.rfind(line_start, 0) == 0) {
        replaced = true;
        if (!with.empty()) out << with << "\n";
        continue;
      }
      out << line << "\n";
    }
    EXPECT_TRUE(replaced) << line_start;
    std::ofstream(path(name)) << out.str();
    return path(name);
  }

  // The sample with the weights written as given (one flow list).
  std::string write_weights(const std::string& name, const std::string& weights_list) {
    save_rnn_weights(path("base.yaml"), sample());
    std::ifstream in(path("base.yaml"));
    std::ostringstream out;
    std::string line;
    while (std::getline(in, line)) {
      if (line.rfind("weights:", 0) == 0) break;
      out << line << "\n";
    }
    out << "weights: [" << weights_list << "]\n";
    std::ofstream(path(name)) << out.str();
    return path(name);
  }

  static std::string list_of(const std::vector<std::string>& values) {
    std::string s;
    for (std::size_t i = 0; i < values.size(); ++i) s += (i ? ", " : "") + values[i];
    return s;
  }

  void expect_load_error(const std::string& file, const std::vector<std::string>& parts) {
    try {
      load_rnn_weights(file);
      ADD_FAILURE() << file << ": loaded; expected an error containing '" << parts.front() << "'";
    } catch (const std::runtime_error& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(file + ": ", 0), 0u) << what;  // names the file first
      for (const std::string& p : parts) EXPECT_NE(what.find(p), std::string::npos) << what;
    }
  }

  fs::path dir_;
};

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

TEST_F(WeightsFile, RoundTripIsBitExact) {
  RnnWeightsFile f = sample();
  f.source = "de \"trainer\" \\ seed: 1 # gen 433\nline two\ttab";
  f.input_scale_s2_per_m = 1.0 / 3.0;
  f.cost = -1;
  // Within the +-100 a set may hold (JordanRnn::kMaxAbsWeight), every digit counts.
  const double specials[] = {0.1,
                             1.0 / 3.0,
                             -0.0,
                             1e-300,
                             4.9406564584124654e-324,
                             99.999999999999986,
                             -2.2250738585072014e-308,
                             -98.765432109876543};
  for (std::size_t i = 0; i < std::size(specials); ++i) f.weights[i * 11] = specials[i];
  save_rnn_weights(path("w.yaml"), f);
  EXPECT_FALSE(fs::exists(path("w.yaml.tmp")));
  const RnnWeightsFile g = load_rnn_weights(path("w.yaml"));
  EXPECT_EQ(g.layer_sizes, f.layer_sizes);
  EXPECT_TRUE(same_bits(g.input_scale_s2_per_m, f.input_scale_s2_per_m));
  EXPECT_TRUE(same_bits(g.gain_n, f.gain_n));
  EXPECT_TRUE(same_bits(g.cost, f.cost));
  EXPECT_EQ(g.source, f.source);
  ASSERT_EQ(g.weights.size(), f.weights.size());
  for (std::size_t i = 0; i < f.weights.size(); ++i) {
    EXPECT_TRUE(same_bits(g.weights[i], f.weights[i])) << i << ": " << g.weights[i] << " vs " << f.weights[i];
  }
  // And the loaded set drives a network of its sizes.
  RnnCompensatorParams p = base_params();
  p.layer_sizes = g.layer_sizes;
  RnnCompensator comp(p);
  EXPECT_NO_THROW(comp.set_weights(g.weights));
}

TEST_F(WeightsFile, CarriesTheInputItWasTrainedOnAndReadsOlderSetsAsThePapers) {
  RnnWeightsFile f = sample();
  f.on_reference_error = true;
  save_rnn_weights(path("error.yaml"), f);
  EXPECT_TRUE(load_rnn_weights(path("error.yaml")).on_reference_error);
  f.on_reference_error = false;
  save_rnn_weights(path("paper.yaml"), f);
  EXPECT_FALSE(load_rnn_weights(path("paper.yaml")).on_reference_error);
  // A set written before the key existed was trained on a_L.
  const std::string older = write_variant("older.yaml", "input:", "");
  EXPECT_FALSE(load_rnn_weights(older).on_reference_error);
}

TEST_F(WeightsFile, ReadsTheDocumentedFormat) {
  std::vector<std::string> w(9, "0.5");
  std::ofstream(path("doc.yaml")) << "format: pmlsm-rnn-weights/1\n"
                                     "layer_sizes: [2, 2, 1]\n"
                                     "input_scale_s2_per_m: 0.02\n"
                                     "gain_n: 300.0\n"
                                     "cost: 5.3            # cost (23)\n"
                                     "source: \"de_trainer seed 1 gen 433\"\n"
                                     "weights: ["
                                  << list_of(w) << "]\n";
  const RnnWeightsFile f = load_rnn_weights(path("doc.yaml"));
  EXPECT_EQ(f.layer_sizes, (std::vector<int>{2, 2, 1}));
  EXPECT_EQ(f.gain_n, 300.0);
  EXPECT_EQ(f.cost, 5.3);
  EXPECT_EQ(f.source, "de_trainer seed 1 gen 433");
  EXPECT_EQ(f.weights, std::vector<double>(9, 0.5));
}

TEST_F(WeightsFile, SaveReplacesAtomicallyWithoutLeavingTmp) {
  RnnWeightsFile f = sample();
  save_rnn_weights(path("w.yaml"), f);
  f.cost = 1.25;
  f.weights[0] = 42.0;
  save_rnn_weights(path("w.yaml"), f);  // over an existing file
  EXPECT_FALSE(fs::exists(path("w.yaml.tmp")));
  const RnnWeightsFile g = load_rnn_weights(path("w.yaml"));
  EXPECT_EQ(g.cost, 1.25);
  EXPECT_EQ(g.weights[0], 42.0);
  std::size_t files = 0;
  for (const auto& entry : fs::directory_iterator(dir_)) {
    EXPECT_EQ(entry.path().extension(), ".yaml") << entry.path();
    ++files;
  }
  EXPECT_EQ(files, 1u);
}

TEST_F(WeightsFile, SaveRejectsInvalidContentAndWritesNothing) {
  RnnWeightsFile f = sample();
  f.weights[3] = kNan;
  try {
    save_rnn_weights(path("w.yaml"), f);
    ADD_FAILURE() << "saved a nan weight";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("weights[3]: must be finite, got nan"), std::string::npos) << e.what();
  }
  f = sample();
  f.weights.pop_back();
  EXPECT_THROW(save_rnn_weights(path("w.yaml"), f), std::runtime_error);
  EXPECT_FALSE(fs::exists(path("w.yaml")));
  EXPECT_FALSE(fs::exists(path("w.yaml.tmp")));
  EXPECT_THROW(save_rnn_weights(path("no/such/dir/w.yaml"), sample()), std::runtime_error);
}

TEST_F(WeightsFile, ValidateNamesTheField) {
  RnnWeightsFile f = sample();
  EXPECT_NO_THROW(validate_rnn_weights(f));
  f.gain_n = 0;
  expect_invalid([&] { validate_rnn_weights(f); }, {"gain_n: must be > 0, got 0"});
  f = sample();
  f.cost = -2;
  expect_invalid([&] { validate_rnn_weights(f); }, {"cost", "-2"});
  f = sample();
  f.layer_sizes = {3, 6, 6, 3, 2};
  expect_invalid([&] { validate_rnn_weights(f); }, {"layer_sizes[4]"});
}

TEST_F(WeightsFile, BadFilesFailNamingTheProblem) {
  expect_load_error(path("missing.yaml"), {"cannot open"});
  expect_load_error(write_variant("unknown.yaml", "cost:", "cost: 5.3\nlearning_rate: 0.1"),
                    {"learning_rate: unknown key"});
  expect_load_error(write_variant("missing_key.yaml", "cost:", ""), {"cost: missing key"});
  expect_load_error(write_variant("tag.yaml", "format:", "format: pmlsm-rnn-weights/2"),
                    {"format: expected 'pmlsm-rnn-weights/1', got 'pmlsm-rnn-weights/2'"});
  expect_load_error(write_variant("sizes.yaml", "layer_sizes:", "layer_sizes: [3, 6, 6, 3, 2]"),
                    {"layer_sizes[4]", "got 2"});
  expect_load_error(write_variant("sizes_text.yaml", "layer_sizes:", "layer_sizes: [3, six, 6, 3, 1]"),
                    {"layer_sizes[1]: expected an integer, got 'six'"});
  expect_load_error(write_variant("gain.yaml", "gain_n:", "gain_n: -1"), {"gain_n: must be > 0, got -1"});
  expect_load_error(write_variant("scale.yaml", "input_scale_s2_per_m:", "input_scale_s2_per_m: fast"),
                    {"input_scale_s2_per_m: expected a number, got 'fast'"});
  expect_load_error(write_variant("dup.yaml", "cost:", "cost: 5.3\ncost: 4.0"), {"cost: duplicate key"});
  expect_load_error(write_variant("input.yaml", "input:", "input: load_velocity"),
                    {"input: expected load_accel or accel_error, got 'load_velocity'"});
  expect_load_error(write_variant("input_dup.yaml", "input:", "input: accel_error\ninput: load_accel"),
                    {"input: duplicate key"});

  std::vector<std::string> w(91, "0.25");
  expect_load_error(write_weights("count.yaml", list_of(std::vector<std::string>(90, "0.25"))),
                    {"weights: expected 91 values", "got 90"});
  std::vector<std::string> with_nan = w;
  with_nan[3] = ".nan";
  expect_load_error(write_weights("nan.yaml", list_of(with_nan)), {"weights[3]: must be finite, got .nan"});
  std::vector<std::string> with_inf = w;
  with_inf[7] = "-.inf";
  expect_load_error(write_weights("inf.yaml", list_of(with_inf)), {"weights[7]: must be finite, got -.inf"});
  std::vector<std::string> with_text = w;
  with_text[5] = "abc";
  expect_load_error(write_weights("text.yaml", list_of(with_text)), {"weights[5]: expected a number, got 'abc'"});
  std::vector<std::string> with_quoted = w;
  with_quoted[6] = "\"0.5\"";
  expect_load_error(write_weights("quoted.yaml", list_of(with_quoted)), {"weights[6]: expected a number"});

  std::ofstream(path("broken.yaml")) << "format: [unclosed\n";
  expect_load_error(path("broken.yaml"), {"YAML parse error"});
  std::ofstream(path("list.yaml")) << "- 1\n- 2\n";
  expect_load_error(path("list.yaml"), {"mapping"});
}

TEST_F(WeightsFile, ImplausibleWeightsAreRefused) {
  // All 1e300: finite, but the compensator would be a +-G_n bang-bang.
  expect_load_error(write_weights("huge.yaml", list_of(std::vector<std::string>(91, "1e300"))),
                    {"weights[0]: must be in [-100, 100]", "got 1e+300"});
  std::vector<std::string> w(91, "0.25");
  w[90] = "-100.5";
  expect_load_error(write_weights("edge.yaml", list_of(w)), {"weights[90]", "got -100.5"});
  w[90] = "-100";
  EXPECT_NO_THROW(load_rnn_weights(write_weights("bound.yaml", list_of(w))));
}

// ---------------------------------------------------------------- weight sets offered to a running compensator

}  // namespace
}  // namespace pmlsm

#include "pmlsm/config/weights_file.hpp"

#include <yaml-cpp/yaml.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <locale>
#include <set>
#include <sstream>
#include <stdexcept>

#include "pmlsm/config/config.hpp"
#include "pmlsm/compensation/jordan_rnn.hpp"
#include "pmlsm/util/atomic_file.hpp"
#include "pmlsm/util/validate.hpp"
#include "config_reading.hpp"
#include "yaml_document.hpp"

namespace pmlsm {

namespace {

const char* const kKeys[] = {"format", "layer_sizes", "input_scale_s2_per_m", "gain_n", "cost", "source", "weights"};
// Optional: absent in sets trained before the key existed (all on the paper's a_L).
const char* const kInputKey = "input";
const char* const kInputLoadAccel = "load_accel";
const char* const kInputAccelError = "accel_error";

using config_reading::describe;

// A YAML number as written: plain (unquoted) scalar, decimal with optional
// exponent, or the YAML special values .nan / .inf / -.inf (returned as such, so
// that the caller reports "must be finite, got .nan"). Parsed with the classic
// locale, so a value written with 17 significant digits reads back exactly.
bool parse_number(const YAML::Node& v, double& out) {
  if (!v.IsScalar() || v.Tag() == "!") return false;  // "!" = quoted string
  const std::string& t = v.Scalar();
  if (t == ".nan" || t == ".NaN" || t == ".NAN") {
    out = std::numeric_limits<double>::quiet_NaN();
    return true;
  }
  for (const char* inf : {".inf", ".Inf", ".INF", "+.inf", "+.Inf", "+.INF"}) {
    if (t == inf) {
      out = std::numeric_limits<double>::infinity();
      return true;
    }
  }
  for (const char* inf : {"-.inf", "-.Inf", "-.INF"}) {
    if (t == inf) {
      out = -std::numeric_limits<double>::infinity();
      return true;
    }
  }
  if (t.empty() || t.find_first_not_of("0123456789+-.eE") != std::string::npos) return false;
  std::istringstream in(t);
  in.imbue(std::locale::classic());
  double x = 0;
  in >> x;
  if (in.fail() || in.peek() != std::char_traits<char>::eof()) return false;
  out = x;
  return true;
}

bool parse_int(const YAML::Node& v, int& out) {
  if (!v.IsScalar() || v.Tag() == "!") return false;
  const std::string& t = v.Scalar();
  if (t.empty() || t.find_first_not_of("0123456789+-") != std::string::npos) return false;
  std::istringstream in(t);
  in.imbue(std::locale::classic());
  long long x = 0;
  in >> x;
  if (in.fail() || in.peek() != std::char_traits<char>::eof()) return false;
  if (x < std::numeric_limits<int>::min() || x > std::numeric_limits<int>::max()) return false;
  out = static_cast<int>(x);
  return true;
}

class Reader {
 public:
  Reader(const YAML::Node& root, std::string origin) : root_(root), origin_(std::move(origin)) {}

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw ConfigError(origin_ + ": " + key + ": " + what);
  }

  void check_keys() const {
    std::set<std::string> seen;
    for (const auto& kv : root_) {
      const std::string key = kv.first.IsScalar() ? kv.first.Scalar() : describe(kv.first);
      bool known = false;
      for (const char* k : kKeys) known = known || key == k;
      known = known || key == kInputKey;
      if (!known) {
        fail(key,
             "unknown key (expected format, layer_sizes, input_scale_s2_per_m, input, gain_n, cost, "
             "source, weights)");
      }
      if (!seen.insert(key).second) fail(key, "duplicate key");
    }
    for (const char* k : kKeys) {
      if (seen.count(k) == 0) fail(k, "missing key");
    }
  }

  YAML::Node get(const char* key) const { return root_[key]; }

  double number(const std::string& key, const YAML::Node& v) const {
    double x = 0;
    if (!parse_number(v, x)) fail(key, "expected a number, got '" + describe(v) + "'");
    if (!std::isfinite(x)) fail(key, "must be finite, got " + v.Scalar());
    return x;
  }

  std::string text(const char* key) const {
    const YAML::Node v = get(key);
    if (!v.IsScalar()) fail(key, "expected a string, got '" + describe(v) + "'");
    return v.Scalar();
  }

  const YAML::Node& root() const { return root_; }

 private:
  YAML::Node root_;
  std::string origin_;
};

std::string index_key(const char* key, std::size_t i) { return std::string(key) + "[" + std::to_string(i) + "]"; }

// 17 significant digits: reads back to the identical double.
std::string format_exact(double v) {
  std::ostringstream out;
  out.imbue(std::locale::classic());
  out.precision(17);
  out << v;
  return out.str();
}

// 15 significant digits when they read back to the identical double, else 17:
// "5.3", not "5.2999999999999998", for the hand-read header values.
std::string format_short(double v) {
  std::ostringstream out;
  out.imbue(std::locale::classic());
  out.precision(15);
  out << v;
  std::istringstream in(out.str());
  in.imbue(std::locale::classic());
  double back = 0;
  in >> back;
  return back == v && std::signbit(back) == std::signbit(v) ? out.str() : format_exact(v);
}

std::string yaml_quoted(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '"') {
      out += "\\\"";
    } else if (c == '\\') {
      out += "\\\\";
    } else if (c == '\n') {
      out += "\\n";
    } else if (c == '\t') {
      out += "\\t";
    } else if (u < 0x20 || u == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02X", u);
      out += buf;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string sizes_text(const std::vector<int>& sizes) {
  std::string out = "[";
  for (std::size_t i = 0; i < sizes.size(); ++i) out += (i ? ", " : "") + std::to_string(sizes[i]);
  return out + "]";
}

std::string render(const RnnWeightsFile& f) {
  std::string out;
  out += "# RNN compensator weights (see common/config/include/pmlsm/config/weights_file.hpp).\n";
  out += std::string("format: ") + kRnnWeightsFormat + "\n";
  out += "layer_sizes: " + sizes_text(f.layer_sizes) + "\n";
  out += "input_scale_s2_per_m: " + format_short(f.input_scale_s2_per_m) + "\n";
  out += std::string(kInputKey) + ": " + (f.on_reference_error ? kInputAccelError : kInputLoadAccel) + "\n";
  out += "gain_n: " + format_short(f.gain_n) + "\n";
  out += "cost: " + format_short(f.cost) + "\n";
  out += "source: " + yaml_quoted(f.source) + "\n";
  out += "# " + std::to_string(f.weights.size()) +
         " values: one neuron per line (incoming weights in the previous layer's order, then the "
         "bias), layer by layer from the first hidden layer\n";
  out += "weights: [\n";
  std::size_t k = 0;
  for (std::size_t l = 1; l < f.layer_sizes.size(); ++l) {
    const auto fan_in = static_cast<std::size_t>(f.layer_sizes[l - 1]) + 1;
    for (int j = 0; j < f.layer_sizes[l]; ++j) {
      out += "  ";
      for (std::size_t i = 0; i < fan_in; ++i, ++k) {
        out += format_exact(f.weights[k]);
        if (k + 1 < f.weights.size()) out += i + 1 < fan_in ? ", " : ",";
      }
      out += "\n";
    }
  }
  out += "]\n";
  return out;
}

}  // namespace

void validate_rnn_weights(const RnnWeightsFile& f) {
  const std::size_t n = JordanRnn::parameter_count(f.layer_sizes);  // throws "layer_sizes[i]: ..."
  require_positive("input_scale_s2_per_m", f.input_scale_s2_per_m);
  require_positive("gain_n", f.gain_n);
  require_finite("cost", f.cost);
  if (!(f.cost >= 0.0 || f.cost == -1.0)) {
    throw std::invalid_argument("cost: must be >= 0, or -1 when unknown, got " + format_value(f.cost));
  }
  if (f.weights.size() != n) {
    throw std::invalid_argument("weights: expected " + std::to_string(n) + " values for layer_sizes " +
                                sizes_text(f.layer_sizes) + ", got " + std::to_string(f.weights.size()));
  }
  for (std::size_t i = 0; i < n; ++i) {
    const std::string key = index_key("weights", i);
    require_in_range(key.c_str(), f.weights[i], -JordanRnn::kMaxAbsWeight, JordanRnn::kMaxAbsWeight);
  }
}

RnnWeightsFile parse_rnn_weights(const std::string& text, const std::string& path) {
  const YAML::Node root = load_yaml_document(text, path);
  if (!root.IsMap()) throw ConfigError(path + ": top level must be a mapping of keys");

  Reader r(root, path);
  r.check_keys();
  RnnWeightsFile f;

  const std::string format = r.text("format");
  if (format != kRnnWeightsFormat) {
    r.fail("format", std::string("expected '") + kRnnWeightsFormat + "', got '" + format + "'");
  }

  const YAML::Node sizes = r.get("layer_sizes");
  if (!sizes.IsSequence()) r.fail("layer_sizes", "expected a list of integers, got '" + describe(sizes) + "'");
  for (std::size_t i = 0; i < sizes.size(); ++i) {
    int x = 0;
    if (!parse_int(sizes[i], x)) {
      r.fail(index_key("layer_sizes", i), "expected an integer, got '" + describe(sizes[i]) + "'");
    }
    f.layer_sizes.push_back(x);
  }
  std::size_t count = 0;
  try {
    count = JordanRnn::parameter_count(f.layer_sizes);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(path + ": " + e.what());
  }

  f.input_scale_s2_per_m = r.number("input_scale_s2_per_m", r.get("input_scale_s2_per_m"));
  if (root[kInputKey]) {
    const std::string input = r.text(kInputKey);
    if (input != kInputLoadAccel && input != kInputAccelError) {
      r.fail(kInputKey,
             std::string("expected ") + kInputLoadAccel + " or " + kInputAccelError + ", got '" + input + "'");
    }
    f.on_reference_error = input == kInputAccelError;
  }
  f.gain_n = r.number("gain_n", r.get("gain_n"));
  f.cost = r.number("cost", r.get("cost"));
  f.source = r.text("source");

  const YAML::Node w = r.get("weights");
  if (!w.IsSequence()) r.fail("weights", "expected a list of numbers, got '" + describe(w) + "'");
  if (w.size() != count) {
    r.fail("weights", "expected " + std::to_string(count) + " values for layer_sizes " + sizes_text(f.layer_sizes) +
                          ", got " + std::to_string(w.size()));
  }
  f.weights.reserve(count);
  for (std::size_t i = 0; i < w.size(); ++i) f.weights.push_back(r.number(index_key("weights", i), w[i]));

  try {
    validate_rnn_weights(f);  // the ranges: scale, gain > 0, cost
  } catch (const std::invalid_argument& e) {
    throw ConfigError(path + ": " + e.what());
  }
  return f;
}

RnnWeightsFile load_rnn_weights(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError(path + ": cannot open file");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_rnn_weights(text.str(), path);
}

void save_rnn_weights(const std::string& path, const RnnWeightsFile& f) {
  try {
    validate_rnn_weights(f);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(path + ": not saved: " + e.what());
  }
  try {
    write_file_atomically(path, render(f));
  } catch (const AtomicWriteError& e) {
    throw ConfigError(path + ": not saved: " + e.what());
  }
}

std::string rnn_weights_misfit(const RnnWeightsFile& w, const SystemParams& p) {
  try {
    validate_rnn_weights(w);
  } catch (const std::exception& e) {
    return e.what();
  }
  if (w.layer_sizes != p.compensator.rnn.layer_sizes) return "layer sizes differ from compensator.rnn.layer_sizes";
  if (w.input_scale_s2_per_m != p.compensator.rnn.input_scale_s2_per_m) {
    return "input scale " + format_value(w.input_scale_s2_per_m) +
           " differs from compensator.rnn.input_scale_s2_per_m " + format_value(p.compensator.rnn.input_scale_s2_per_m);
  }
  if (w.on_reference_error != p.compensator.rnn.on_reference_error) {
    return std::string("input ") + (w.on_reference_error ? kInputAccelError : kInputLoadAccel) +
           " differs from compensator.rnn.on_reference_error " +
           (p.compensator.rnn.on_reference_error ? "true" : "false");
  }
  if (w.gain_n != p.compensator.rnn.gain_n) {
    return "gain " + format_value(w.gain_n) + " N differs from compensator.rnn.gain_n " +
           format_value(p.compensator.rnn.gain_n);
  }
  return {};
}

WeightSetGate::WeightSetGate(const SystemParams& params) : params_(params) {}

std::string WeightSetGate::offer(const RnnWeightsFile& set, std::uint64_t version, const char* origin) {
  std::string why = rnn_weights_misfit(set, params_);
  if (why.empty() && taken_ > 0 && version <= version_) {
    why = "version " + std::to_string(version) + " does not increase on version " + std::to_string(version_) +
          " in use (a rollback: start de_trainer with --first-version above " + std::to_string(version_) + ")";
  }
  char cost[32];
  std::snprintf(cost, sizeof cost, set.cost < 0 ? "unknown" : "%.6g", set.cost);
  if (!why.empty()) {
    ++refused_;
    last_log_ = "weight set " + std::to_string(version) + " from '" + set.source + "' (" + origin + ", cost " + cost +
                ") refused, keeping version " + std::to_string(version_) + ": " + why;
    return why;
  }
  ++taken_;
  last_log_ = "weight set " + std::to_string(version) + " from '" + set.source + "' (" + origin + ", cost " + cost +
              ") taken, replacing version " + std::to_string(version_);
  version_ = version;
  return {};
}

}  // namespace pmlsm

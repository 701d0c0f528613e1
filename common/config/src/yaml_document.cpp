#include "yaml_document.hpp"

#include <set>
#include <sstream>
#include <vector>

#include "pmlsm/config/config.hpp"

namespace pmlsm {

namespace {

// Walks the parser's events before the tree is built: yaml-cpp's node builder
// keeps the first of two equal keys and shares aliased nodes, so neither a
// duplicate nor an alias is visible in the tree.
class DocumentChecker : public YAML::EventHandler {
 public:
  explicit DocumentChecker(std::string origin) : origin_(std::move(origin)) {}

  void OnDocumentStart(const YAML::Mark&) override {}
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark& mark, YAML::anchor_t) override {
    // An empty key ("? " alone, or ": value") has no name to read or report.
    if (!levels_.empty() && levels_.back().map && levels_.back().at_key)
      fail(mark, "a key must be a plain name, got an empty key");
    node(mark, "~", false);
    value_done();
  }
  void OnAlias(const YAML::Mark& mark, YAML::anchor_t) override {
    fail(mark, "anchors and aliases (&name, *name) are not accepted: each value is written out");
  }
  void OnAnchor(const YAML::Mark& mark, const std::string& name) override {
    fail(mark, "anchors and aliases (&" + name + ") are not accepted: each value is written out");
  }
  void OnScalar(const YAML::Mark& mark, const std::string&, YAML::anchor_t, const std::string& value) override {
    node(mark, value, false);
    value_done();
  }
  void OnSequenceStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    node(mark, "", true);
    open(mark, false);
  }
  void OnSequenceEnd() override { close(); }
  void OnMapStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    node(mark, "", true);
    open(mark, true);
  }
  void OnMapEnd() override { close(); }

 private:
  struct Level {
    bool map = false;
    bool at_key = true;
    std::string key;  ///< the key whose value is being read, for the duplicate's path
    std::set<std::string> keys;
  };

  [[noreturn]] void fail(const YAML::Mark& mark, const std::string& what) const {
    throw ConfigError(origin_ + ": line " + std::to_string(mark.line + 1) + ", column " +
                      std::to_string(mark.column + 1) + ": " + what);
  }

  std::string path() const {
    std::string out;
    for (const Level& l : levels_) {
      if (!l.map || l.at_key) continue;
      out += (out.empty() ? "" : ".") + l.key;
    }
    return out;
  }

  // A node starts: as a mapping's key, or as a value (of a mapping, a list or the document).
  void node(const YAML::Mark& mark, const std::string& scalar, bool collection) {
    if (levels_.empty() || !levels_.back().map) return;
    Level& l = levels_.back();
    if (!l.at_key) return;  // a value: the level flips back to keys when it ends
    if (collection) fail(mark, "a key must be a plain name, not a list or mapping");
    if (!l.keys.insert(scalar).second) {
      const std::string parent = path();
      fail(mark, (parent.empty() ? scalar : parent + "." + scalar) + ": duplicate key");
    }
    l.key = scalar;
  }

  void open(const YAML::Mark& mark, bool map) {
    if (static_cast<int>(levels_.size()) >= kMaxYamlDepth) {
      fail(mark, "nested deeper than " + std::to_string(kMaxYamlDepth) + " levels");
    }
    levels_.push_back(Level{map, true, {}, {}});
  }

  void close() {
    levels_.pop_back();
    value_done();
  }

  // Called after a key or a value has been read completely (a scalar at once, a
  // collection at its end).
  void value_done() {
    if (!levels_.empty() && levels_.back().map) levels_.back().at_key = !levels_.back().at_key;
  }

 private:
  std::string origin_;
  std::vector<Level> levels_;
};

}  // namespace

YAML::Node load_yaml_document(const std::string& text, const std::string& origin) {
  if (text.size() > kMaxYamlBytes) {
    throw ConfigError(origin + ": " + std::to_string(text.size()) + " bytes, more than the " +
                      std::to_string(kMaxYamlBytes) + " a config may have");
  }
  if (text.find('\0') != std::string::npos) {
    throw ConfigError(origin + ": contains a NUL byte: not a YAML text file");
  }
  try {
    std::istringstream in(text);
    YAML::Parser parser(in);
    DocumentChecker checker(origin);
    if (parser.HandleNextDocument(checker) && parser.HandleNextDocument(checker)) {
      throw ConfigError(origin + ": more than one YAML document ('---'): a config is one document");
    }
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(origin + ": YAML parse error: " + e.what());
  }
}

}  // namespace pmlsm

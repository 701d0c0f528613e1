// Decoded fields as numbers and as text: Field::as_double/to_string, Decoded::find and the
// ros2-topic-echo style YAML of MessageSchema::to_yaml, rebuilt from the flat field paths.

#include <algorithm>
#include <charconv>
#include <cmath>
#include <string_view>
#include <type_traits>

#include "pmlsm/introspect/cdr_schema.hpp"

namespace pmlsm::introspect {
namespace {

/// Shortest text that reads back as the same double (what ros2 echo, via Python, prints),
/// always recognisable as a float in YAML: "2.0", "1.0e+16", ".inf", ".nan".
std::string double_text(double value) {
  if (std::isnan(value)) return ".nan";
  if (std::isinf(value)) return value > 0 ? ".inf" : "-.inf";
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  std::string text(buffer, result.ptr);
  if (text.find('.') == std::string::npos) {
    const std::size_t exponent = text.find('e');
    text.insert(exponent == std::string::npos ? text.size() : exponent, ".0");
  }
  return text;
}

/// YAML scalar for a string: single-quoted ('' for '), or double-quoted with escapes when it
/// holds control characters, which single quotes cannot carry.
std::string quoted(const std::string& text) {
  bool has_control = false;
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7f) has_control = true;
  }
  std::string out;
  out.reserve(text.size() + 2);
  if (!has_control) {
    out += '\'';
    for (const char c : text) {
      if (c == '\'') out += '\'';
      out += c;
    }
    out += '\'';
    return out;
  }
  constexpr char kHex[] = "0123456789abcdef";
  out += '"';
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    switch (c) {
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      case '\r': out += "\\r"; break;
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      default:
        if (byte < 0x20 || byte == 0x7f) {
          out += "\\x";
          out += kHex[byte >> 4];
          out += kHex[byte & 0xf];
        } else {
          out += c;
        }
    }
  }
  out += '"';
  return out;
}

/// One step of a field path: a member name ("stamp") or an element index ("[3]").
struct PathStep {
  std::string_view text;  // name, or the digits of the index
  bool is_index = false;
  bool operator==(const PathStep& other) const { return is_index == other.is_index && text == other.text; }
};

void split_path(std::string_view path, std::vector<PathStep>& steps) {
  steps.clear();
  std::size_t i = 0;
  while (i < path.size()) {
    if (path[i] == '.') {
      ++i;
    } else if (path[i] == '[') {
      const std::size_t close = path.find(']', i);
      const std::size_t end = close == std::string_view::npos ? path.size() : close;
      steps.push_back({path.substr(i + 1, end - i - 1), true});
      i = end + 1;
    } else {
      const std::size_t end = std::min(path.find_first_of(".[", i), path.size());
      steps.push_back({path.substr(i, end - i), false});
      i = end;
    }
  }
}

}  // namespace

std::optional<double> Field::as_double() const {
  return std::visit(
      [](const auto& held) -> std::optional<double> {
        using Held = std::decay_t<decltype(held)>;
        if constexpr (std::is_same_v<Held, std::string>) {
          return std::nullopt;
        } else if constexpr (std::is_same_v<Held, bool>) {
          return held ? 1.0 : 0.0;
        } else {
          return static_cast<double>(held);
        }
      },
      value);
}

std::string Field::to_string() const {
  return std::visit(
      [](const auto& held) -> std::string {
        using Held = std::decay_t<decltype(held)>;
        if constexpr (std::is_same_v<Held, std::string>) {
          return quoted(held);
        } else if constexpr (std::is_same_v<Held, bool>) {
          return held ? "true" : "false";
        } else if constexpr (std::is_same_v<Held, double>) {
          return double_text(held);
        } else {
          return std::to_string(held);
        }
      },
      value);
}

const Field* Decoded::find(const std::string& path) const {
  for (const auto& field : fields) {
    if (field.path == path) return &field;
  }
  return nullptr;
}

// Each field is a leaf; its path's steps that differ from the previous field's open new YAML
// nodes. As ros2 echo prints: a member's children are indented by 2, a sequence's "- " items
// sit at the member's own indentation, and the first child of an item shares the "- " line.
std::string MessageSchema::to_yaml(const Decoded& decoded) {
  std::string out;
  out.reserve(decoded.fields.size() * 32);
  std::vector<PathStep> previous;
  std::vector<PathStep> steps;
  std::vector<std::size_t> indents;
  std::string item_prefix;  // "- " (nested: "- - ") waiting for the first line of its item
  for (const auto& field : decoded.fields) {
    split_path(field.path, steps);
    if (steps.empty()) continue;
    std::size_t common = 0;
    while (common + 1 < steps.size() && common < previous.size() && steps[common] == previous[common]) {
      ++common;
    }
    indents.assign(steps.size(), 0);
    for (std::size_t i = 1; i < steps.size(); ++i) {
      const bool sequence_of_member = !steps[i - 1].is_index && steps[i].is_index;
      indents[i] = indents[i - 1] + (sequence_of_member ? 0 : 2);
    }
    item_prefix.clear();
    for (std::size_t i = common; i < steps.size(); ++i) {
      const bool leaf = i + 1 == steps.size();
      if (item_prefix.empty()) item_prefix.assign(indents[i], ' ');
      if (steps[i].is_index) {
        item_prefix += "- ";
        if (!leaf) continue;
        out += item_prefix;
      } else {
        out += item_prefix;
        out += steps[i].text;
        out += ':';
        if (leaf) out += ' ';
      }
      item_prefix.clear();
      if (leaf) out += field.to_string();
      out += '\n';
    }
    previous.swap(steps);
  }
  return out;
}

}  // namespace pmlsm::introspect

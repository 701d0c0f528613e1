// IDL text -> type tree (MessageSchema::parse) and XCDR1 bytes -> fields (MessageSchema::decode).
//
// The parser is a small recursive-descent one over a token list. Types must be declared before
// use, as IDL requires, so the type tree is acyclic and every walk over it terminates. Size caps
// (elements per type, nesting depth) keep hostile schemas from exhausting memory or the stack.
// The decoder walks the tree with a cursor that checks every read against the sample size, so
// no input reads out of bounds; it stops at the first inconsistency and reports where.

#include <algorithm>
#include <array>
#include <charconv>
#include <cstring>
#include <deque>
#include <limits>
#include <map>
#include <sstream>
#include <string_view>
#include <utility>

#include "pmlsm/introspect/cdr_schema.hpp"
#include "pmlsm/introspect/ros2_msg.hpp"

namespace pmlsm::introspect {
// Named rather than anonymous: MessageSchema::Impl holds these types, and a class with linkage
// may not hold types of an anonymous namespace outside the main file (-Wsubobject-linkage, in
// a unity build).
namespace schema_detail {

// ------------------------------------------------------------------------------ type tree

enum class Kind : std::uint8_t {
  Boolean,
  Char,
  Int8,
  UInt8,
  Int16,
  UInt16,
  Int32,
  UInt32,
  Int64,
  UInt64,
  Float,
  Double,
  Enum,
  String,
  Sequence,
  Array,
  Struct,
};
constexpr std::size_t kKindCount = static_cast<std::size_t>(Kind::Struct) + 1;

/// CDR size (= alignment) of the fixed-size kinds; 0 for the others.
std::size_t primitive_size(Kind kind) {
  switch (kind) {
    case Kind::Boolean:
    case Kind::Char:
    case Kind::Int8:
    case Kind::UInt8: return 1;
    case Kind::Int16:
    case Kind::UInt16: return 2;
    case Kind::Int32:
    case Kind::UInt32:
    case Kind::Float:
    case Kind::Enum: return 4;
    case Kind::Int64:
    case Kind::UInt64:
    case Kind::Double: return 8;
    default: return 0;
  }
}

bool is_integer_kind(Kind kind) {
  return primitive_size(kind) != 0 && kind != Kind::Boolean && kind != Kind::Char && kind != Kind::Float &&
         kind != Kind::Double;
}

struct TypeNode;

struct Member {
  std::string name;
  const TypeNode* type = nullptr;
};

struct TypeNode {
  Kind kind = Kind::Struct;
  std::string name;                   // scoped name of structs and enums
  std::uint32_t length = 0;           // string/sequence: bound (0 = unbounded); array: element count
  const TypeNode* element = nullptr;  // sequence and array element
  std::vector<Member> members;        // struct members, base struct's first
  // Derived when the node is added:
  std::size_t min_size = 0;      // fewest CDR bytes a value takes: bounds sequence counts by data
  std::size_t walk_size = 1;     // nodes of a static walk, fixed arrays expanded: caps type size
  std::size_t fixed_leaves = 0;  // leaf fields outside sequences: reserve() hint
  int depth = 1;                 // nesting depth: caps the decoder's recursion
};

// A type larger than this is surely not a message (and would make field_paths() huge).
constexpr std::size_t kMaxWalkSize = std::size_t{1} << 20;
constexpr int kMaxTypeDepth = 64;
// Modules, sequence<...> and parentheses nested deeper than this are refused: parse recursion.
constexpr int kMaxSyntaxNesting = 64;
constexpr std::size_t kHeaderSize = 4;  // CDR encapsulation header

// ------------------------------------------------------------------------------ tokens

enum class TokenKind : std::uint8_t { Identifier, Number, Literal, Punct, End };

struct Token {
  TokenKind kind = TokenKind::End;
  std::string text;  // literals without their quotes
  int line = 0;
};

[[noreturn]] void fail_at(int line, const std::string& token, const std::string& what) {
  throw SchemaError("IDL line " + std::to_string(line) + ", at '" + token + "': " + what);
}

std::string printable(char c) {
  const auto byte = static_cast<unsigned char>(c);
  if (byte >= 0x20 && byte < 0x7f) return std::string(1, c);
  constexpr char kHex[] = "0123456789abcdef";
  return std::string("\\x") + kHex[byte >> 4] + kHex[byte & 0xf];
}

bool is_identifier_start(char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_'; }
bool is_identifier_char(char c) { return is_identifier_start(c) || (c >= '0' && c <= '9'); }
bool is_digit(char c) { return c >= '0' && c <= '9'; }

// A lexer: one loop, a branch per token kind (comments, preprocessor lines, identifiers, numbers,
// literals, punctuation); splitting it would spread one state over several functions.
// NOLINTNEXTLINE(readability-function-size)
std::vector<Token> tokenize(const std::string& idl) {
  std::vector<Token> tokens;
  tokens.reserve(idl.size() / 6 + 1);
  const std::size_t size = idl.size();
  std::size_t i = 0;
  int line = 1;
  bool at_line_start = true;  // only blanks so far: a '#' here starts a preprocessor line
  while (i < size) {
    const char c = idl[i];
    if (c == '\n') {
      ++line;
      ++i;
      at_line_start = true;
      continue;
    }
    if (c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v') {
      ++i;
      continue;
    }
    if (c == '#' && at_line_start) {
      // #include, #pragma, guards: the schema text is already flattened, nothing to expand.
      while (i < size && idl[i] != '\n') {
        if (idl[i] == '\\' && i + 1 < size && idl[i + 1] == '\n') {
          ++line;  // a trailing backslash continues the directive on the next line
          ++i;
        }
        ++i;
      }
      continue;
    }
    at_line_start = false;
    const int token_line = line;
    if (c == '/' && i + 1 < size && idl[i + 1] == '/') {
      while (i < size && idl[i] != '\n') ++i;
      continue;
    }
    if (c == '/' && i + 1 < size && idl[i + 1] == '*') {
      const std::size_t end = idl.find("*/", i + 2);
      if (end == std::string::npos) fail_at(token_line, "/*", "unterminated comment");
      line += static_cast<int>(std::count(idl.begin() + static_cast<std::ptrdiff_t>(i),
                                          idl.begin() + static_cast<std::ptrdiff_t>(end), '\n'));
      i = end + 2;
      continue;
    }
    Token token;
    token.line = token_line;
    const std::size_t start = i;
    if (is_identifier_start(c)) {
      while (i < size && is_identifier_char(idl[i])) ++i;
      token.kind = TokenKind::Identifier;
      token.text = idl.substr(start, i - start);
    } else if (is_digit(c) || (c == '.' && i + 1 < size && is_digit(idl[i + 1]))) {
      // Integers and floats alike; only integers are ever evaluated (bounds).
      const bool hex = c == '0' && i + 1 < size && (idl[i + 1] == 'x' || idl[i + 1] == 'X');
      while (i < size) {
        const char d = idl[i];
        const bool exponent_sign = !hex && (d == '+' || d == '-') && (idl[i - 1] == 'e' || idl[i - 1] == 'E');
        if (!is_identifier_char(d) && d != '.' && !exponent_sign) break;
        ++i;
      }
      token.kind = TokenKind::Number;
      token.text = idl.substr(start, i - start);
    } else if (c == '"' || c == '\'') {
      ++i;
      while (i < size && idl[i] != c && idl[i] != '\n') i += (idl[i] == '\\' && i + 1 < size) ? 2 : 1;
      if (i >= size || idl[i] != c) fail_at(token_line, std::string(1, c), "unterminated literal");
      token.kind = TokenKind::Literal;
      token.text = idl.substr(start + 1, i - start - 1);
      ++i;
    } else if (c == ':' && i + 1 < size && idl[i + 1] == ':') {
      i += 2;
      token.kind = TokenKind::Punct;
      token.text = "::";
    } else if (std::strchr("{}();,<>[]=:@+-*/%|&^~", c) != nullptr) {
      ++i;
      token.kind = TokenKind::Punct;
      token.text = std::string(1, c);
    } else {
      fail_at(token_line, printable(c), "unexpected character");
    }
    tokens.push_back(std::move(token));
  }
  Token end;
  end.line = line;
  tokens.push_back(std::move(end));
  return tokens;
}

// ------------------------------------------------------------------------------ parser

struct Symbol {
  enum class What : std::uint8_t { Type, Constant };
  What what = What::Type;
  const TypeNode* type = nullptr;       // for types
  std::optional<std::int64_t> integer;  // for constants whose value is an integer expression
};

/// A constant as declared, for the ROS 2 message files (ros2_message_files).
struct DeclaredConstant {
  std::string scoped_name;
  const TypeNode* type = nullptr;
  std::optional<std::int64_t> integer;
  std::string text;  ///< the value's tokens, literals re-quoted
  int line = 0;
};

struct Annotation {
  std::string name;
  std::size_t args_begin = 0;  // token range inside the parentheses (empty when none)
  std::size_t args_end = 0;
};

struct PrimitiveWord {
  const char* word;
  Kind kind;
};
constexpr PrimitiveWord kPrimitiveWords[] = {
    {"boolean", Kind::Boolean}, {"char", Kind::Char},     {"octet", Kind::UInt8}, {"int8", Kind::Int8},
    {"uint8", Kind::UInt8},     {"short", Kind::Int16},   {"int16", Kind::Int16}, {"uint16", Kind::UInt16},
    {"int32", Kind::Int32},     {"uint32", Kind::UInt32}, {"int64", Kind::Int64}, {"uint64", Kind::UInt64},
    {"float", Kind::Float},     {"double", Kind::Double},
};

constexpr const char* kUnsupportedTypes[] = {"wchar", "wstring", "fixed", "any", "Object", "ValueBase", "map"};
constexpr const char* kUnsupportedConstructs[] = {
    "union", "interface", "exception", "valuetype", "bitset", "bitmask", "native", "abstract",
    "local", "custom",    "eventtype", "component", "home",   "import",  "typeid", "typeprefix"};

class Parser {
 public:
  Parser(const std::string& idl, std::deque<TypeNode>& nodes) : tokens_(tokenize(idl)), nodes_(nodes) {}

  void parse_specification() {
    while (peek().kind != TokenKind::End) parse_definition();
  }

  /// The struct named `scoped_name` (no leading "::"), or nullptr.
  const TypeNode* find_struct(const std::string& scoped_name) const {
    const auto found = symbols_.find(scoped_name);
    if (found == symbols_.end() || found->second.what != Symbol::What::Type) return nullptr;
    return found->second.type->kind == Kind::Struct ? found->second.type : nullptr;
  }

  const std::vector<std::string>& struct_names() const { return struct_names_; }
  const std::vector<DeclaredConstant>& constants() const { return constants_; }

  std::string struct_list() const {
    std::string list;
    for (const auto& name : struct_names_) list += (list.empty() ? "" : ", ") + name;
    return list.empty() ? "(none)" : list;
  }

 private:
  const Token& peek() const { return tokens_[pos_]; }
  const Token& next() {
    const Token& token = tokens_[pos_];
    if (pos_ + 1 < tokens_.size()) ++pos_;  // the End token stays current
    return token;
  }
  static bool is(const Token& token, std::string_view text) {
    return (token.kind == TokenKind::Identifier || token.kind == TokenKind::Punct) && token.text == text;
  }
  bool peek_is(std::string_view text) const { return is(peek(), text); }
  bool accept(std::string_view text) {
    if (!peek_is(text)) return false;
    next();
    return true;
  }
  [[noreturn]] void fail(const Token& at, const std::string& what) const {
    fail_at(at.line, at.kind == TokenKind::End ? "end of input" : at.text, what);
  }
  void expect(std::string_view text, const std::string& context) {
    if (!accept(text)) fail(peek(), "expected '" + std::string(text) + "' " + context);
  }
  std::string expect_identifier(const std::string& what) {
    if (peek().kind != TokenKind::Identifier) fail(peek(), "expected " + what);
    return next().text;
  }
  void enter_nesting(const Token& at) {
    if (++nesting_ > kMaxSyntaxNesting) fail(at, "nested too deeply");
  }
  void leave_nesting() { --nesting_; }

  std::string scoped(const std::string& name) const {
    std::string full;
    for (const auto& module : scope_) full += module + "::";
    return full + name;
  }

  /// "a::b", "::a::b" or "b" as written.
  std::string parse_scoped_name() {
    std::string name;
    if (accept("::")) name = "::";
    name += expect_identifier("a name");
    while (accept("::")) name += "::" + expect_identifier("a name after '::'");
    return name;
  }

  /// IDL scoping: innermost enclosing module first, then outwards; "::x" is absolute.
  const Symbol* lookup(const std::string& name) const {
    if (name.compare(0, 2, "::") == 0) {
      const auto found = symbols_.find(name.substr(2));
      return found == symbols_.end() ? nullptr : &found->second;
    }
    for (std::size_t depth = scope_.size() + 1; depth-- > 0;) {
      std::string candidate;
      for (std::size_t i = 0; i < depth; ++i) candidate += scope_[i] + "::";
      candidate += name;
      const auto found = symbols_.find(candidate);
      if (found != symbols_.end()) return &found->second;
    }
    return nullptr;
  }

  const TypeNode* resolve_type(const std::string& name, const Token& at) const {
    const Symbol* symbol = lookup(name);
    if (symbol == nullptr) fail(at, "unknown type '" + name + "'");
    if (symbol->what != Symbol::What::Type) fail(at, "'" + name + "' is a constant, not a type");
    return symbol->type;
  }

  void define(const std::string& name, const Token& at, Symbol symbol) {
    const std::string full = scoped(name);
    if (symbols_.count(full) != 0) fail(at, "redefinition of '" + full + "'");
    if (symbol.what == Symbol::What::Type && symbol.type->kind == Kind::Struct && symbol.type->name == full) {
      struct_names_.push_back(full);
    }
    symbols_.emplace(full, std::move(symbol));
  }

  /// Stores `node` with its derived sizes; refuses types too large or too deep to handle.
  const TypeNode* add_node(TypeNode node, const Token& at) {
    const std::size_t fixed = primitive_size(node.kind);
    if (fixed != 0) {
      node.min_size = fixed;
      node.fixed_leaves = 1;
    } else if (node.kind == Kind::String) {
      node.min_size = 4;
      node.fixed_leaves = 1;
    } else if (node.kind == Kind::Sequence) {
      node.min_size = 4;
      node.walk_size = 1 + node.element->walk_size;
      node.depth = node.element->depth + 1;
    } else if (node.kind == Kind::Array) {
      const TypeNode& element = *node.element;
      if (node.length > (kMaxWalkSize - 1) / element.walk_size) {
        fail(at, "array of more than " + std::to_string(kMaxWalkSize) + " elements");
      }
      node.walk_size = 1 + node.length * element.walk_size;
      node.min_size = node.length * element.min_size;
      node.fixed_leaves = node.length * element.fixed_leaves;
      node.depth = element.depth + 1;
    } else {  // struct
      for (const auto& member : node.members) {
        node.walk_size += member.type->walk_size;
        node.min_size += member.type->min_size;
        node.fixed_leaves += member.type->fixed_leaves;
        node.depth = std::max(node.depth, member.type->depth + 1);
        if (node.walk_size > kMaxWalkSize) {
          fail(at, "struct of more than " + std::to_string(kMaxWalkSize) + " elements");
        }
      }
    }
    if (node.walk_size > kMaxWalkSize) {
      fail(at, "type of more than " + std::to_string(kMaxWalkSize) + " elements");
    }
    if (node.depth > kMaxTypeDepth) fail(at, "types nested too deeply");
    nodes_.push_back(std::move(node));
    return &nodes_.back();
  }

  const TypeNode* primitive(Kind kind, const Token& at) {
    const TypeNode*& cached = primitives_[static_cast<std::size_t>(kind)];
    if (cached == nullptr) {
      TypeNode node;
      node.kind = kind;
      cached = add_node(std::move(node), at);
    }
    return cached;
  }

  // --- definitions

  void parse_definition() {
    const std::vector<Annotation> annotations = parse_annotations();
    const Token& token = peek();
    if (token.kind == TokenKind::End) {
      if (!annotations.empty()) fail(token, "annotation without a definition");
      return;
    }
    if (accept(";")) return;
    if (is(token, "module")) return parse_module();
    if (is(token, "struct")) return parse_struct();
    if (is(token, "enum")) return parse_enum();
    if (is(token, "typedef")) return parse_typedef();
    if (is(token, "const")) return parse_const();
    for (const char* construct : kUnsupportedConstructs) {
      if (is(token, construct)) fail(token, "unsupported IDL construct");
    }
    if (is(token, "}")) fail(token, "unbalanced '}'");
    fail(token, "expected a definition (module, struct, enum, typedef or const)");
  }

  std::vector<Annotation> parse_annotations() {
    std::vector<Annotation> annotations;
    while (peek_is("@")) {
      const Token& at = next();
      Annotation annotation;
      annotation.name = parse_scoped_name();
      if (annotation.name == "annotation" && peek().kind == TokenKind::Identifier) {
        // An annotation definition: declares nothing the decoder needs.
        next();
        expect("{", "after the annotation name");
        skip_balanced("{", "}", at);
        accept(";");
        continue;
      }
      if (accept("(")) {
        annotation.args_begin = pos_;
        skip_balanced("(", ")", at);
        annotation.args_end = pos_ - 1;  // the closing ')'
      }
      annotations.push_back(std::move(annotation));
    }
    return annotations;
  }

  /// Skips to just after the closer matching an opener already consumed.
  void skip_balanced(std::string_view opener, std::string_view closer, const Token& start) {
    for (int depth = 1; depth > 0;) {
      if (peek().kind == TokenKind::End) {
        fail(start, "missing '" + std::string(closer) + "' (opened at line " + std::to_string(start.line) + ")");
      }
      const Token& token = next();
      if (is(token, opener)) ++depth;
      if (is(token, closer)) --depth;
    }
  }

  void parse_module() {
    const Token& keyword = next();
    const std::string name = expect_identifier("a module name");
    expect("{", "after module '" + name + "'");
    enter_nesting(keyword);
    scope_.push_back(name);
    while (!peek_is("}")) {
      if (peek().kind == TokenKind::End) {
        fail(peek(), "missing '}' closing module '" + name + "' (opened at line " + std::to_string(keyword.line) + ")");
      }
      parse_definition();
    }
    next();
    scope_.pop_back();
    leave_nesting();
    accept(";");
  }

  void parse_struct() {
    const Token& keyword = next();
    const Token& name_token = peek();
    const std::string name = expect_identifier("a struct name");
    if (accept(";")) return;  // forward declaration: only the definition matters
    TypeNode node;
    node.kind = Kind::Struct;
    node.name = scoped(name);
    if (accept(":")) {
      // Inheritance: XCDR1 writes the base's members first, as if declared here.
      const Token& base_token = peek();
      const TypeNode* base = resolve_type(parse_scoped_name(), base_token);
      if (base->kind != Kind::Struct) fail(base_token, "a struct can only inherit a struct");
      node.members = base->members;
    }
    expect("{", "after struct '" + name + "'");
    while (!peek_is("}")) {
      const Token& token = peek();
      if (token.kind == TokenKind::End || is(token, "struct") || is(token, "module") || is(token, "typedef") ||
          is(token, "enum") || is(token, "const")) {
        fail(token, "missing '}' closing struct '" + name + "' (opened at line " + std::to_string(keyword.line) + ")");
      }
      parse_member(node);
    }
    next();
    accept(";");
    define(name, name_token, Symbol{Symbol::What::Type, add_node(std::move(node), name_token), {}});
  }

  void parse_member(TypeNode& owner) {
    for (const auto& annotation : parse_annotations()) {
      // XCDR1 encodes optional members with a parameter header the decoder does not read.
      if (annotation.name == "optional" && !annotation_is_false(annotation)) {
        fail(peek(), "@optional members are not supported");
      }
    }
    const TypeNode* type = parse_type_spec();
    do {
      const Token& name_token = peek();
      const std::string name = expect_identifier("a member name");
      const TypeNode* member_type = parse_array_dimensions(type, name_token);
      for (const auto& member : owner.members) {
        if (member.name == name) fail(name_token, "duplicate member '" + name + "'");
      }
      owner.members.push_back(Member{name, member_type});
    } while (accept(","));
    expect(";", "after a member");
  }

  bool annotation_is_false(const Annotation& annotation) const {
    return annotation.args_end == annotation.args_begin + 1 &&
           (is(tokens_[annotation.args_begin], "FALSE") || is(tokens_[annotation.args_begin], "false"));
  }

  /// name[N][M]: an array of N arrays of M elements.
  const TypeNode* parse_array_dimensions(const TypeNode* type, const Token& name_token) {
    std::vector<std::uint32_t> dimensions;
    while (accept("[")) {
      dimensions.push_back(parse_bound());
      expect("]", "after an array dimension");
    }
    for (auto dimension = dimensions.rbegin(); dimension != dimensions.rend(); ++dimension) {
      TypeNode node;
      node.kind = Kind::Array;
      node.length = *dimension;
      node.element = type;
      type = add_node(std::move(node), name_token);
    }
    return type;
  }

  const TypeNode* parse_type_spec() {
    const Token& token = peek();
    if (token.kind != TokenKind::Identifier && !is(token, "::")) fail(token, "expected a type");
    if (token.kind == TokenKind::Identifier) {
      if (is(token, "unsigned")) {
        next();
        if (accept("short")) return primitive(Kind::UInt16, token);
        if (accept("long")) return primitive(accept("long") ? Kind::UInt64 : Kind::UInt32, token);
        fail(peek(), "expected 'short' or 'long' after 'unsigned'");
      }
      if (is(token, "long")) {
        next();
        if (accept("long")) return primitive(Kind::Int64, token);
        if (peek_is("double")) fail(peek(), "long double is not supported");
        return primitive(Kind::Int32, token);
      }
      for (const auto& word : kPrimitiveWords) {
        if (is(token, word.word)) {
          next();
          return primitive(word.kind, token);
        }
      }
      if (is(token, "string")) {
        next();
        TypeNode node;
        node.kind = Kind::String;
        if (accept("<")) {
          node.length = parse_bound();
          expect(">", "after the string bound");
        }
        return add_node(std::move(node), token);
      }
      if (is(token, "sequence")) {
        next();
        expect("<", "after 'sequence'");
        enter_nesting(token);
        TypeNode node;
        node.kind = Kind::Sequence;
        node.element = parse_type_spec();
        if (accept(",")) node.length = parse_bound();
        expect(">", "closing the sequence");
        leave_nesting();
        return add_node(std::move(node), token);
      }
      for (const char* unsupported : kUnsupportedTypes) {
        if (is(token, unsupported)) fail(token, "unsupported type");
      }
    }
    return resolve_type(parse_scoped_name(), token);
  }

  void parse_enum() {
    next();
    const Token& name_token = peek();
    const std::string name = expect_identifier("an enum name");
    expect("{", "after enum '" + name + "'");
    TypeNode node;
    node.kind = Kind::Enum;
    node.name = scoped(name);
    std::int64_t value = 0;  // enumerators count from 0 unless @value says otherwise
    while (!peek_is("}")) {
      for (const auto& annotation : parse_annotations()) {
        if (annotation.name == "value") {
          const auto given = evaluate(annotation.args_begin, annotation.args_end, 0);
          if (!given) fail(peek(), "@value needs an integer constant");
          value = *given;
        }
      }
      const Token& enumerator = peek();
      // Enumerators live in the enclosing scope, as in C; consts and bounds may use them.
      define(expect_identifier("an enumerator"), enumerator, Symbol{Symbol::What::Constant, nullptr, value});
      if (value < std::numeric_limits<std::int64_t>::max()) ++value;
      if (!accept(",")) break;
    }
    expect("}", "closing enum '" + name + "'");
    accept(";");
    define(name, name_token, Symbol{Symbol::What::Type, add_node(std::move(node), name_token), {}});
  }

  void parse_typedef() {
    next();
    const TypeNode* type = parse_type_spec();
    do {
      const Token& name_token = peek();
      const std::string name = expect_identifier("a typedef name");
      define(name, name_token, Symbol{Symbol::What::Type, parse_array_dimensions(type, name_token), {}});
    } while (accept(","));
    expect(";", "after a typedef");
  }

  void parse_const() {
    next();
    const TypeNode* type = parse_type_spec();
    const Token& name_token = peek();
    const std::string name = expect_identifier("a constant name");
    expect("=", "after constant '" + name + "'");
    const std::size_t begin = pos_;
    while (!peek_is(";")) {
      if (peek().kind == TokenKind::End) fail(peek(), "missing ';' after constant '" + name + "'");
      next();
    }
    const std::size_t end = pos_;
    next();
    if (begin == end) fail(name_token, "constant '" + name + "' without a value");
    // Only integer constants matter (as bounds); others (strings, floats) are just declared.
    std::optional<std::int64_t> integer;
    if (is_integer_kind(type->kind)) integer = evaluate(begin, end, 0);
    std::string text;
    for (std::size_t i = begin; i < end; ++i) {
      const Token& t = tokens_[i];
      text += t.kind == TokenKind::Literal ? "\"" + t.text + "\"" : t.text;
    }
    constants_.push_back(DeclaredConstant{scoped(name), type, integer, text, name_token.line});
    define(name, name_token, Symbol{Symbol::What::Constant, nullptr, integer});
  }

  // --- integer constant expressions: literals, constants, + - * / % and parentheses

  /// A bound or array dimension, up to the next ',', '>' or ']' outside parentheses.
  std::uint32_t parse_bound() {
    const Token& start = peek();
    const std::size_t begin = pos_;
    for (int parens = 0;;) {
      const Token& token = peek();
      if (token.kind == TokenKind::End) fail(token, "unterminated bound");
      if (parens == 0 && (is(token, ",") || is(token, ">") || is(token, "]"))) break;
      if (is(token, "(")) ++parens;
      if (is(token, ")") && --parens < 0) break;
      next();
    }
    const auto value = evaluate(begin, pos_, 0);
    if (!value || *value < 1 || *value > std::numeric_limits<std::uint32_t>::max()) {
      fail(start, "a bound must be a positive integer constant below 2^32");
    }
    return static_cast<std::uint32_t>(*value);
  }

  std::optional<std::int64_t> evaluate(std::size_t begin, std::size_t end, int depth) const {
    std::size_t at = begin;
    const auto value = evaluate_sum(at, end, depth);
    if (!value || at != end) return std::nullopt;
    return value;
  }

  std::optional<std::int64_t> evaluate_sum(std::size_t& at, std::size_t end, int depth) const {
    auto left = evaluate_product(at, end, depth);
    while (left && at < end && (is(tokens_[at], "+") || is(tokens_[at], "-"))) {
      const bool plus = is(tokens_[at++], "+");
      const auto right = evaluate_product(at, end, depth);
      std::int64_t result = 0;
      if (!right ||
          (plus ? __builtin_add_overflow(*left, *right, &result) : __builtin_sub_overflow(*left, *right, &result))) {
        return std::nullopt;
      }
      left = result;
    }
    return left;
  }

  std::optional<std::int64_t> evaluate_product(std::size_t& at, std::size_t end, int depth) const {
    auto left = evaluate_unary(at, end, depth);
    while (left && at < end && (is(tokens_[at], "*") || is(tokens_[at], "/") || is(tokens_[at], "%"))) {
      const std::string& op = tokens_[at++].text;
      const auto right = evaluate_unary(at, end, depth);
      if (!right) return std::nullopt;
      std::int64_t result = 0;
      if (op == "*") {
        if (__builtin_mul_overflow(*left, *right, &result)) return std::nullopt;
      } else {
        if (*right == 0 || (*right == -1 && *left == std::numeric_limits<std::int64_t>::min())) {
          return std::nullopt;
        }
        result = op == "/" ? *left / *right : *left % *right;
      }
      left = result;
    }
    return left;
  }

  std::optional<std::int64_t> evaluate_unary(std::size_t& at, std::size_t end, int depth) const {
    if (at >= end || depth > kMaxSyntaxNesting) return std::nullopt;
    const Token& token = tokens_[at];
    if (is(token, "-") || is(token, "+")) {
      ++at;
      const auto operand = evaluate_unary(at, end, depth + 1);
      if (!operand || (is(token, "-") && *operand == std::numeric_limits<std::int64_t>::min())) {
        return std::nullopt;
      }
      return is(token, "-") ? -*operand : *operand;
    }
    if (is(token, "(")) {
      ++at;
      const auto inner = evaluate_sum(at, end, depth + 1);
      if (!inner || at >= end || !is(tokens_[at], ")")) return std::nullopt;
      ++at;
      return inner;
    }
    if (token.kind == TokenKind::Number) {
      ++at;
      return integer_literal(token.text);
    }
    if (token.kind == TokenKind::Identifier || is(token, "::")) {
      std::string name;
      if (is(tokens_[at], "::")) {
        name = "::";
        ++at;
      }
      while (at < end && tokens_[at].kind == TokenKind::Identifier) {
        name += tokens_[at++].text;
        if (at + 1 < end && is(tokens_[at], "::")) {
          name += "::";
          ++at;
        } else {
          break;
        }
      }
      const Symbol* symbol = lookup(name);
      if (symbol == nullptr || symbol->what != Symbol::What::Constant) return std::nullopt;
      return symbol->integer;
    }
    return std::nullopt;
  }

  static std::optional<std::int64_t> integer_literal(const std::string& text) {
    int base = 10;
    std::size_t skip = 0;
    if (text.size() > 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X')) {
      base = 16;
      skip = 2;
    } else if (text.size() > 1 && text[0] == '0') {
      base = 8;
      skip = 1;
    }
    std::uint64_t value = 0;
    const char* first = text.data() + skip;
    const char* last = text.data() + text.size();
    const auto [end, error] = std::from_chars(first, last, value, base);
    if (error != std::errc() || end != last ||
        value > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) {
      return std::nullopt;
    }
    return static_cast<std::int64_t>(value);
  }

  std::vector<Token> tokens_;
  std::size_t pos_ = 0;
  std::deque<TypeNode>& nodes_;
  std::vector<std::string> scope_;           // enclosing modules
  std::map<std::string, Symbol> symbols_;    // by scoped name without leading "::"
  std::vector<std::string> struct_names_;    // in definition order, for "unknown type" errors
  std::vector<DeclaredConstant> constants_;  // in definition order
  std::array<const TypeNode*, kKindCount> primitives_{};
  int nesting_ = 0;
};

/// "::a::b::C", "a/b/C" (ROS style) and "a::b::C" all -> "a::b::C".
std::string normalized_type_name(const std::string& requested) {
  std::string name;
  name.reserve(requested.size() + 8);
  for (const char c : requested) {
    if (c == '/') {
      name += "::";
    } else if (c != ' ' && c != '\t' && c != '\n' && c != '\r') {
      name += c;
    }
  }
  while (name.compare(0, 2, "::") == 0) name.erase(0, 2);
  return name;
}

// ------------------------------------------------------------------------------ decoder

/// One pass over one sample. Invariant: pos_ <= size_; every read checks the bytes left first.
class SampleDecoder {
 public:
  SampleDecoder(const std::uint8_t* data, std::size_t size, Decoded& out) : data_(data), size_(size), out_(out) {
    path_.reserve(96);
  }

  void run(const TypeNode& root) {
    if (size_ < kHeaderSize) {
      out_.error = "sample of " + std::to_string(size_) + " bytes is shorter than the 4-byte encapsulation header";
      return;
    }
    // Byte 0 is 0 and byte 1 the representation for CDR_BE (0) and CDR_LE (1); the others
    // (PL_CDR, XCDR2 kinds, XML) need parameter lists or delimiter headers not handled here.
    if (data_[0] != 0 || data_[1] > 1) {
      out_.error = "unsupported encapsulation " + encapsulation_text() +
                   ": only plain CDR (XCDR1: 0x0000 big-, 0x0001 little-endian) is decoded";
      return;
    }
    little_endian_ = data_[1] == 1;
    pos_ = kHeaderSize;
    reserve_fields(root.fixed_leaves);
    decode(root);
  }

 private:
  std::string encapsulation_text() const {
    constexpr char kHex[] = "0123456789abcdef";
    std::string text = "0x";
    for (int i = 0; i < 2; ++i) text += {kHex[data_[i] >> 4], kHex[data_[i] & 0xf]};
    static constexpr std::pair<std::uint16_t, const char*> kNames[] = {
        {0x0002, "PL_CDR_BE"},  {0x0003, "PL_CDR_LE"},  {0x0006, "CDR2_BE"},
        {0x0007, "CDR2_LE"},    {0x0008, "D_CDR2_BE"},  {0x0009, "D_CDR2_LE"},
        {0x000a, "PL_CDR2_BE"}, {0x000b, "PL_CDR2_LE"}, {0x0004, "XML"},
    };
    const auto kind = static_cast<std::uint16_t>((data_[0] << 8) | data_[1]);
    for (const auto& [value, name] : kNames) {
      if (value == kind) return text + " (" + name + ")";
    }
    return text;
  }

  bool fail(const std::string& what, std::size_t at) {
    out_.error = "at byte " + std::to_string(at) + ", field '" + path_ + "': " + what;
    return false;
  }

  /// Alignment (1, 2, 4 or 8) counts from the first byte after the encapsulation header.
  bool align(std::size_t alignment) {
    const std::size_t misalignment = (pos_ - kHeaderSize) & (alignment - 1);
    if (misalignment == 0) return true;
    const std::size_t padding = alignment - misalignment;
    if (size_ - pos_ < padding) return fail("sample ends inside the alignment padding", pos_);
    pos_ += padding;
    return true;
  }

  /// An unsigned integer of `bytes` bytes, aligned to its size, in the sample's byte order.
  bool read_unsigned(std::size_t bytes, std::uint64_t& value) {
    if (!align(bytes)) return false;
    if (size_ - pos_ < bytes) {
      return fail("sample ends: " + std::to_string(bytes) + " bytes needed, " + std::to_string(size_ - pos_) + " left",
                  pos_);
    }
    value = 0;
    for (std::size_t i = 0; i < bytes; ++i) {
      const std::size_t shift = 8 * (little_endian_ ? i : bytes - 1 - i);
      value |= static_cast<std::uint64_t>(data_[pos_ + i]) << shift;
    }
    pos_ += bytes;
    return true;
  }

  template <class T>
  void add(T value) {
    Field& field = out_.fields.emplace_back();
    field.path = path_;
    field.value.emplace<T>(std::move(value));
  }

  void reserve_fields(std::size_t more) {
    auto& fields = out_.fields;
    const std::size_t wanted = fields.size() + more;
    // Geometric growth: nested sequences reserve repeatedly and must not reallocate each time.
    if (wanted > fields.capacity()) fields.reserve(std::max(wanted, 2 * fields.capacity()));
  }

  void push_index(std::size_t index) {
    char digits[24];
    const auto result = std::to_chars(digits, digits + sizeof digits, index);
    path_ += '[';
    path_.append(digits, result.ptr);
    path_ += ']';
  }

  bool decode(const TypeNode& type) {
    std::uint64_t raw = 0;
    switch (type.kind) {
      case Kind::Boolean: {
        const std::size_t at = pos_;
        if (!read_unsigned(1, raw)) return false;
        if (raw > 1) return fail("invalid boolean value " + std::to_string(raw), at);
        add(raw == 1);
        return true;
      }
      case Kind::Char:
        if (!read_unsigned(1, raw)) return false;
        add(raw == 0 ? std::string() : std::string(1, static_cast<char>(raw)));
        return true;
      case Kind::Int8:
        if (!read_unsigned(1, raw)) return false;
        add(std::int64_t{static_cast<std::int8_t>(raw)});
        return true;
      case Kind::Int16:
        if (!read_unsigned(2, raw)) return false;
        add(std::int64_t{static_cast<std::int16_t>(raw)});
        return true;
      case Kind::Int32:
        if (!read_unsigned(4, raw)) return false;
        add(std::int64_t{static_cast<std::int32_t>(raw)});
        return true;
      case Kind::Int64:
        if (!read_unsigned(8, raw)) return false;
        add(static_cast<std::int64_t>(raw));
        return true;
      case Kind::UInt8:
      case Kind::UInt16:
      case Kind::UInt32:
      case Kind::UInt64:
      case Kind::Enum:
        if (!read_unsigned(primitive_size(type.kind), raw)) return false;
        add(std::uint64_t{raw});
        return true;
      case Kind::Float: {
        if (!read_unsigned(4, raw)) return false;
        const auto bits = static_cast<std::uint32_t>(raw);
        float value = 0;
        std::memcpy(&value, &bits, sizeof value);
        add(double{value});
        return true;
      }
      case Kind::Double: {
        if (!read_unsigned(8, raw)) return false;
        double value = 0;
        std::memcpy(&value, &raw, sizeof value);
        add(value);
        return true;
      }
      case Kind::String: return decode_string(type);
      case Kind::Sequence: return decode_sequence(type);
      case Kind::Array:
        for (std::size_t i = 0; i < type.length; ++i) {
          const std::size_t path_size = path_.size();
          push_index(i);
          if (!decode(*type.element)) return false;
          path_.resize(path_size);
        }
        return true;
      case Kind::Struct:
        for (const auto& member : type.members) {
          const std::size_t path_size = path_.size();
          if (!path_.empty()) path_ += '.';
          path_ += member.name;
          if (!decode(*member.type)) return false;
          path_.resize(path_size);
        }
        return true;
    }
    return fail("internal error: unknown type kind", pos_);
  }

  /// uint32 length including the terminating NUL, then the bytes.
  bool decode_string(const TypeNode& type) {
    std::uint64_t length = 0;
    if (!read_unsigned(4, length)) return false;
    const std::size_t at = pos_ - 4;
    if (length == 0) {  // not what Fast CDR writes for "", but it reads it as ""
      add(std::string());
      return true;
    }
    if (length > size_ - pos_) {
      return fail(
          "string length " + std::to_string(length) + " exceeds the " + std::to_string(size_ - pos_) + " bytes left",
          at);
    }
    if (data_[pos_ + length - 1] != 0) {
      return fail("string of " + std::to_string(length) + " bytes does not end in NUL", at);
    }
    if (type.length != 0 && length - 1 > type.length) {
      return fail(
          "string of " + std::to_string(length - 1) + " characters exceeds its bound " + std::to_string(type.length),
          at);
    }
    const auto* first = reinterpret_cast<const char*>(data_ + pos_);
    add(std::string(first, static_cast<std::size_t>(length - 1)));
    pos_ += length;
    return true;
  }

  /// uint32 count, then the elements.
  bool decode_sequence(const TypeNode& type) {
    std::uint64_t count = 0;
    if (!read_unsigned(4, count)) return false;
    const std::size_t at = pos_ - 4;
    if (type.length != 0 && count > type.length) {
      return fail("sequence count " + std::to_string(count) + " exceeds its bound " + std::to_string(type.length), at);
    }
    // Every element takes at least min_size bytes: a count the data cannot hold is corrupt,
    // and checking it here bounds the loop (and the reserve) by the sample size.
    const std::size_t element_min_size = std::max<std::size_t>(type.element->min_size, 1);
    if (count > (size_ - pos_) / element_min_size) {
      return fail("sequence count " + std::to_string(count) + " needs at least " +
                      std::to_string(count * element_min_size) + " bytes, " + std::to_string(size_ - pos_) + " left",
                  at);
    }
    reserve_fields(static_cast<std::size_t>(count) * type.element->fixed_leaves);
    for (std::size_t i = 0; i < count; ++i) {
      const std::size_t path_size = path_.size();
      push_index(i);
      if (!decode(*type.element)) return false;
      path_.resize(path_size);
    }
    return true;
  }

  const std::uint8_t* data_;
  std::size_t size_;
  Decoded& out_;
  std::size_t pos_ = kHeaderSize;
  bool little_endian_ = true;
  std::string path_;  // of the value being decoded: "stamp.tick", "weights[3]"
};

void collect_paths(const TypeNode& type, std::string& path, std::vector<std::string>& paths) {
  const std::size_t path_size = path.size();
  switch (type.kind) {
    case Kind::Struct:
      for (const auto& member : type.members) {
        if (!path.empty()) path += '.';
        path += member.name;
        collect_paths(*member.type, path, paths);
        path.resize(path_size);
      }
      return;
    case Kind::Array:
      for (std::size_t i = 0; i < type.length; ++i) {
        path += '[' + std::to_string(i) + ']';
        collect_paths(*type.element, path, paths);
        path.resize(path_size);
      }
      return;
    case Kind::Sequence:
      path += "[]";
      collect_paths(*type.element, path, paths);
      path.resize(path_size);
      return;
    default: paths.push_back(path); return;
  }
}

}  // namespace schema_detail

using namespace schema_detail;

struct MessageSchema::Impl {
  std::deque<TypeNode> nodes;  // every type of the IDL; a deque keeps the links between them valid
  const TypeNode* root = nullptr;
  std::string type_name;
};

MessageSchema::MessageSchema(std::shared_ptr<const Impl> impl) : impl_(std::move(impl)) {}

MessageSchema MessageSchema::parse(const std::string& idl, const std::string& type_name) {
  auto impl = std::make_shared<Impl>();
  Parser parser(idl, impl->nodes);
  parser.parse_specification();
  impl->type_name = normalized_type_name(type_name);
  impl->root = parser.find_struct(impl->type_name);
  if (impl->root == nullptr) {
    throw SchemaError("unknown type '" + type_name + "': the IDL defines the structs " + parser.struct_list());
  }
  return MessageSchema(std::move(impl));
}

const std::string& MessageSchema::type_name() const { return impl_->type_name; }

std::vector<std::string> MessageSchema::field_paths() const {
  std::vector<std::string> paths;
  paths.reserve(impl_->root->fixed_leaves);
  std::string path;
  collect_paths(*impl_->root, path, paths);
  return paths;
}

Decoded MessageSchema::decode(const std::uint8_t* data, std::size_t size) const {
  Decoded decoded;
  if (data == nullptr) size = 0;
  try {
    SampleDecoder(data, size, decoded).run(*impl_->root);
  } catch (const std::exception& error) {  // only allocation failures can get here
    decoded.error = std::string("decoding stopped: ") + error.what();
  }
  return decoded;
}

}  // namespace pmlsm::introspect

// ------------------------------------------------------------------------------ ROS 2 .msg files

namespace pmlsm::introspect {
namespace {

using schema_detail::DeclaredConstant;
using schema_detail::Kind;
using schema_detail::TypeNode;

// rosidl's field and constant names (rosidl_adapter/parser.py): fields lower case with single
// underscores inside, constants upper case.
bool is_ros2_field_name(const std::string& name) {
  if (name.empty() || !(name[0] >= 'a' && name[0] <= 'z') || name.back() == '_') return false;
  for (std::size_t i = 0; i < name.size(); ++i) {
    const char c = name[i];
    if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_')) return false;
    if (c == '_' && name[i - 1] == '_') return false;
  }
  return true;
}

bool is_ros2_constant_name(const std::string& name) {
  if (name.empty() || !(name[0] >= 'A' && name[0] <= 'Z')) return false;
  for (const char c : name) {
    if (!((c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_')) return false;
  }
  return true;
}

const char* ros2_primitive(Kind kind) {
  switch (kind) {
    case Kind::Boolean: return "bool";
    case Kind::Char: return "char";
    case Kind::Int8: return "int8";
    case Kind::UInt8: return "uint8";
    case Kind::Int16: return "int16";
    case Kind::UInt16: return "uint16";
    case Kind::Int32: return "int32";
    case Kind::UInt32: return "uint32";
    case Kind::Int64: return "int64";
    case Kind::UInt64: return "uint64";
    case Kind::Float: return "float32";
    case Kind::Double: return "float64";
    default: return nullptr;
  }
}

class Ros2MsgWriter {
 public:
  explicit Ros2MsgWriter(std::string package) : module_(std::move(package) + "::msg::") {}

  /// The .msg type of a member's type: IDL string<N> is string<=N, sequence<T, N> is T[<=N],
  /// T name[N] is T[N], a struct of this package its name.
  std::string type_of(const TypeNode& type, const std::string& where) const {
    if (const char* primitive = ros2_primitive(type.kind)) return primitive;
    switch (type.kind) {
      case Kind::String: return type.length > 0 ? "string<=" + std::to_string(type.length) : "string";
      case Kind::Sequence:
        return element_of(*type.element, where) + (type.length > 0 ? "[<=" + std::to_string(type.length) + "]" : "[]");
      case Kind::Array: return element_of(*type.element, where) + "[" + std::to_string(type.length) + "]";
      case Kind::Struct: return message_name(type.name, where);
      case Kind::Enum: refuse(where, "an enum ('" + type.name + "'): a ROS 2 message has none; use an integer");
      default: refuse(where, "a type a ROS 2 message cannot hold");
    }
  }

  /// "pmlsm_msgs::msg::Stamp" -> "Stamp"; a struct outside the package's msg module is refused.
  std::string message_name(const std::string& scoped, const std::string& where) const {
    if (scoped.compare(0, module_.size(), module_) != 0 || scoped.find("::", module_.size()) != std::string::npos) {
      refuse(where, "'" + scoped + "' is not a message of " + module_.substr(0, module_.size() - 2));
    }
    return scoped.substr(module_.size());
  }

  /// A constant of module <package>::msg::<Name>_Constants: the message it belongs to, or "".
  std::string owner_of(const DeclaredConstant& c) const {
    const std::string suffix = "_Constants::";
    const auto end = c.scoped_name.rfind("::");
    if (c.scoped_name.compare(0, module_.size(), module_) != 0 || end < suffix.size()) return "";
    const std::string module = c.scoped_name.substr(module_.size(), end + 2 - module_.size());
    if (module.size() <= suffix.size() || module.compare(module.size() - suffix.size(), suffix.size(), suffix) != 0) {
      return "";
    }
    return module.substr(0, module.size() - suffix.size());
  }

  std::string constant_line(const DeclaredConstant& c) const {
    const std::string name = c.scoped_name.substr(c.scoped_name.rfind("::") + 2);
    const std::string where = "constant '" + c.scoped_name + "' (IDL line " + std::to_string(c.line) + ")";
    if (!is_ros2_constant_name(name)) refuse(where, "a ROS 2 constant name is upper case letters, digits and '_'");
    const char* primitive = ros2_primitive(c.type->kind);
    if (primitive == nullptr && c.type->kind != Kind::String)
      refuse(where, "a ROS 2 constant is a primitive or string");
    const std::string value = c.integer ? std::to_string(*c.integer) : c.text;
    return std::string(primitive != nullptr ? primitive : "string") + " " + name + "=" + value + "\n";
  }

  [[noreturn]] static void refuse(const std::string& where, const std::string& what) {
    throw SchemaError("ROS 2 message: " + where + ": " + what);
  }

 private:
  std::string element_of(const TypeNode& element, const std::string& where) const {
    if (element.kind == Kind::Sequence || element.kind == Kind::Array) {
      refuse(where, "a list of lists: a ROS 2 message field has one dimension");
    }
    return type_of(element, where);
  }

  std::string module_;
};

}  // namespace

std::vector<Ros2MessageFile> ros2_message_files(const std::string& idl, const std::string& package) {
  std::deque<schema_detail::TypeNode> nodes;
  schema_detail::Parser parser(idl, nodes);
  parser.parse_specification();
  const Ros2MsgWriter writer(package);
  std::vector<Ros2MessageFile> files;
  for (const std::string& scoped : parser.struct_names()) {
    const std::string name = writer.message_name(scoped, "struct '" + scoped + "'");
    Ros2MessageFile file{name, ""};
    for (const DeclaredConstant& c : parser.constants()) {
      if (writer.owner_of(c) == name) file.text += writer.constant_line(c);
    }
    if (!file.text.empty()) file.text += "\n";
    for (const auto& member : parser.find_struct(scoped)->members) {
      const std::string where = "field '" + scoped + "::" + member.name + "'";
      if (!is_ros2_field_name(member.name)) {
        Ros2MsgWriter::refuse(where, "a ROS 2 field name is lower case letters, digits and single '_'");
      }
      file.text += writer.type_of(*member.type, where) + " " + member.name + "\n";
    }
    files.push_back(std::move(file));
  }
  for (const DeclaredConstant& c : parser.constants()) {
    const std::string owner = writer.owner_of(c);
    const bool owned =
        std::any_of(files.begin(), files.end(), [&](const Ros2MessageFile& f) { return f.name == owner; });
    if (!owned) {
      Ros2MsgWriter::refuse("constant '" + c.scoped_name + "' (IDL line " + std::to_string(c.line) + ")",
                            "not in a module <Message>_Constants of " + package + "::msg beside its message");
    }
  }
  return files;
}

std::string ros2_message_definition(const std::string& idl, const std::string& package, const std::string& name) {
  const std::vector<Ros2MessageFile> files = ros2_message_files(idl, package);
  const auto file_of = [&](const std::string& n) -> const Ros2MessageFile* {
    for (const Ros2MessageFile& f : files) {
      if (f.name == n) return &f;
    }
    return nullptr;
  };
  const Ros2MessageFile* root = file_of(name);
  if (root == nullptr) throw SchemaError("ROS 2 message: no message '" + name + "' in the IDL");
  // The messages it uses, each once, in the order first met (depth first): the root's text, then
  // "MSG: <package>/<Name>" blocks, as rosbag2 stores a definition (MCAP's ros2msg profile).
  std::vector<std::string> order{name};
  for (std::size_t i = 0; i < order.size(); ++i) {
    std::istringstream lines(file_of(order[i])->text);
    for (std::string line; std::getline(lines, line);) {
      // "Type[<=8] name" is a field; "uint8 NAME=1" a constant ('=' after the type).
      const std::size_t space = line.find(' ');
      if (space == std::string::npos || line.find('=', space) != std::string::npos) continue;
      const std::string used = line.substr(0, std::min(space, line.find_first_of("[<")));
      if (file_of(used) == nullptr) continue;
      if (std::find(order.begin(), order.end(), used) == order.end()) order.push_back(used);
    }
  }
  std::string text = root->text;
  for (std::size_t i = 1; i < order.size(); ++i) {
    text += std::string(80, '=') + "\nMSG: " + package + "/" + order[i] + "\n" + file_of(order[i])->text;
  }
  return text;
}

}  // namespace pmlsm::introspect

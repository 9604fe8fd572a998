#include "moreau/expr/expression.h"

#include "expression_arithmetic.h"
#include "native_tape.h"

#include <bit>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <unordered_map>
#include <stdexcept>
#include <string>
#include <utility>

#include "moreau/platform/number_text.h"

namespace moreau::expr {

namespace {

// Constant folding computes with the interpreter's operations (apply below, Tape::run_interpreted), so that
// a folded constant is bit for bit what the tape would compute at run time.
using arithmetic::max_of;
using arithmetic::min_of;
using arithmetic::select_le_of;
using arithmetic::sign_of;

double apply(Op op, double x, double y, double z, double w) {
  switch (op) {
    case Op::kConst:
    case Op::kVar: break;
    case Op::kAdd: return x + y;
    case Op::kSub: return x - y;
    case Op::kMul: return x * y;
    case Op::kDiv: return x / y;
    case Op::kPow: return std::pow(x, y);
    case Op::kNeg: return -x;
    case Op::kSin: return std::sin(x);
    case Op::kCos: return std::cos(x);
    case Op::kTan: return std::tan(x);
    case Op::kAsin: return std::asin(x);
    case Op::kAcos: return std::acos(x);
    case Op::kAtan: return std::atan(x);
    case Op::kAtan2: return std::atan2(x, y);
    case Op::kSinh: return std::sinh(x);
    case Op::kCosh: return std::cosh(x);
    case Op::kTanh: return std::tanh(x);
    case Op::kExp: return std::exp(x);
    case Op::kLog: return std::log(x);
    case Op::kSqrt: return std::sqrt(x);
    case Op::kAbs: return std::fabs(x);
    case Op::kMin: return min_of(x, y);
    case Op::kMax: return max_of(x, y);
    case Op::kSign: return sign_of(x);
    case Op::kSquare: return x * x;
    case Op::kSelectLe: return select_le_of(x, y, z, w);
    case Op::kSinCos: break;  // tape only, never folded
  }
  return 0.0;
}

// Number of operands of a graph node; 0 for leaves and for ops that no builder may create.
int arity(Op op) {
  switch (op) {
    case Op::kConst:
    case Op::kVar:
    case Op::kSinCos: return 0;
    case Op::kAdd:
    case Op::kSub:
    case Op::kMul:
    case Op::kDiv:
    case Op::kPow:
    case Op::kAtan2:
    case Op::kMin:
    case Op::kMax: return 2;
    case Op::kSelectLe: return 4;
    default: return 1;
  }
}

bool is_commutative(Op op) { return op == Op::kAdd || op == Op::kMul; }

const char* function_name(Op op) {
  switch (op) {
    case Op::kSin: return "sin";
    case Op::kCos: return "cos";
    case Op::kTan: return "tan";
    case Op::kAsin: return "asin";
    case Op::kAcos: return "acos";
    case Op::kAtan: return "atan";
    case Op::kAtan2: return "atan2";
    case Op::kSinh: return "sinh";
    case Op::kCosh: return "cosh";
    case Op::kTanh: return "tanh";
    case Op::kExp: return "exp";
    case Op::kLog: return "log";
    case Op::kSqrt: return "sqrt";
    case Op::kAbs: return "abs";
    case Op::kMin: return "min";
    case Op::kMax: return "max";
    case Op::kSign: return "sign";
    default: return nullptr;
  }
}

struct FunctionInfo {
  std::string_view name;
  Op op;
  int args;
};
constexpr FunctionInfo kFunctions[] = {
    {"sin", Op::kSin, 1},   {"cos", Op::kCos, 1},     {"tan", Op::kTan, 1},   {"asin", Op::kAsin, 1}, {"acos", Op::kAcos, 1},
    {"atan", Op::kAtan, 1}, {"atan2", Op::kAtan2, 2}, {"sinh", Op::kSinh, 1}, {"cosh", Op::kCosh, 1}, {"tanh", Op::kTanh, 1},
    {"exp", Op::kExp, 1},   {"log", Op::kLog, 1},     {"sqrt", Op::kSqrt, 1}, {"abs", Op::kAbs, 1},   {"min", Op::kMin, 2},
    {"max", Op::kMax, 2},   {"pow", Op::kPow, 2},
};

// ---------------------------------------------------------------------------------------------------------
// Parser: recursive descent over the grammar in the header. Every recursive step goes through a DepthGuard,
// so the C++ stack depth is bounded by kMaxDepth whatever the input.

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v'; }
bool is_digit(char c) { return c >= '0' && c <= '9'; }
bool is_name_start(char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_'; }
bool is_name_char(char c) { return is_name_start(c) || is_digit(c); }

class Parser {
 public:
  Parser(Graph& graph, std::string_view text, const Graph::Resolver& resolve) : g_(graph), s_(text), resolve_(resolve) {}

  Node parse() {
    if (s_.size() > kMaxTextLength) {
      throw ExpressionError("expression longer than " + std::to_string(kMaxTextLength) + " characters", kMaxTextLength);
    }
    skip_space();
    if (pos_ == s_.size()) throw ExpressionError("empty expression", 0);
    Node n = parse_expr();
    skip_space();
    if (pos_ != s_.size()) {
      check_character(pos_);
      throw ExpressionError("trailing input after expression", pos_);
    }
    return n;
  }

 private:
  struct DepthGuard {
    DepthGuard(Parser& p, std::size_t at) : p(p) {
      if (++p.depth_ > kMaxDepth) {
        throw ExpressionError("nesting deeper than " + std::to_string(kMaxDepth), at);
      }
    }
    ~DepthGuard() { --p.depth_; }
    DepthGuard(const DepthGuard&) = delete;
    DepthGuard& operator=(const DepthGuard&) = delete;
    Parser& p;
  };

  bool at_end() const { return pos_ >= s_.size(); }
  char peek() const { return at_end() ? '\0' : s_[pos_]; }
  void skip_space() {
    while (!at_end() && is_space(s_[pos_])) ++pos_;
  }

  // Throws for a byte that can start no token; binary and non-ASCII input ends up here.
  void check_character(std::size_t at) const {
    const unsigned char c = static_cast<unsigned char>(s_[at]);
    static constexpr std::string_view kTokenChars = "+-*/^(),.";
    if (is_name_char(static_cast<char>(c)) || kTokenChars.find(static_cast<char>(c)) != std::string_view::npos) {
      return;
    }
    if (c >= 0x21 && c <= 0x7e) {
      throw ExpressionError(std::string("unexpected character '") + static_cast<char>(c) + "'", at);
    }
    char buf[48];
    std::snprintf(buf, sizeof buf, "unexpected byte 0x%02X", static_cast<unsigned>(c));
    throw ExpressionError(buf, at);
  }

  Node parse_expr() {
    Node left = parse_term();
    for (;;) {
      skip_space();
      const char c = peek();
      if (c != '+' && c != '-') return left;
      ++pos_;
      Node right = parse_term();
      left = g_.binary(c == '+' ? Op::kAdd : Op::kSub, left, right);
    }
  }

  Node parse_term() {
    Node left = parse_unary();
    for (;;) {
      skip_space();
      const char c = peek();
      if (c != '*' && c != '/') return left;
      ++pos_;
      Node right = parse_unary();
      left = g_.binary(c == '*' ? Op::kMul : Op::kDiv, left, right);
    }
  }

  Node parse_unary() {
    skip_space();
    const char c = peek();
    if (c == '-' || c == '+') {
      DepthGuard guard(*this, pos_);
      ++pos_;
      Node operand = parse_unary();
      return c == '-' ? g_.unary(Op::kNeg, operand) : operand;
    }
    return parse_power();
  }

  Node parse_power() {
    Node base = parse_primary();
    skip_space();
    if (peek() != '^') return base;
    DepthGuard guard(*this, pos_);
    ++pos_;
    Node exponent = parse_unary();  // right-associative: 2^3^2 = 2^(3^2)
    return g_.binary(Op::kPow, base, exponent);
  }

  Node parse_primary() {
    skip_space();
    if (at_end()) throw ExpressionError("unexpected end of expression", pos_);
    const char c = s_[pos_];
    if (is_digit(c) || c == '.') return parse_number();
    if (is_name_start(c)) return parse_name();
    if (c == '(') {
      DepthGuard guard(*this, pos_);
      ++pos_;
      Node inner = parse_expr();
      expect_close();
      return inner;
    }
    check_character(pos_);
    throw ExpressionError(std::string("expected a number, a name or '(' but found '") + c + "'", pos_);
  }

  void expect_close() {
    skip_space();
    if (peek() == ')') {
      ++pos_;
      return;
    }
    if (!at_end()) check_character(pos_);
    throw ExpressionError("expected ')'", pos_);
  }

  Node parse_number() {
    const std::size_t start = pos_;
    std::size_t digits = 0;
    while (!at_end() && is_digit(s_[pos_])) ++pos_, ++digits;
    if (peek() == '.') {
      ++pos_;
      while (!at_end() && is_digit(s_[pos_])) ++pos_, ++digits;
    }
    if (digits == 0) throw ExpressionError("malformed number: expected a digit", start);
    if (peek() == 'e' || peek() == 'E') {
      ++pos_;
      if (peek() == '+' || peek() == '-') ++pos_;
      if (!is_digit(peek())) throw ExpressionError("malformed number: expected digits in the exponent", pos_);
      while (!at_end() && is_digit(s_[pos_])) ++pos_;
    }
    const std::string_view token = s_.substr(start, pos_ - start);
    double value = 0.0;
    const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
    if (ec == std::errc::result_out_of_range) {
      if (overflows(token)) {
        throw ExpressionError("number out of range '" + std::string(token) + "'", start);
      }
      value = 0.0;  // below the smallest subnormal: rounds to zero, as the literal would in C++
    } else if (ec != std::errc() || end != token.data() + token.size()) {
      throw ExpressionError("malformed number '" + std::string(token) + "'", start);
    }
    if (!std::isfinite(value)) throw ExpressionError("number out of range '" + std::string(token) + "'", start);
    return g_.constant(value);
  }

  // For a literal from_chars rejected as out of range: true if it is too large, false if too small.
  // The decimal magnitude is the position of the first non-zero digit relative to the point plus the
  // exponent; the cut between the two failure modes is nowhere near zero, so this estimate is exact enough.
  static bool overflows(std::string_view token) {
    long long magnitude = 0;
    bool seen_point = false, seen_nonzero = false;
    std::size_t i = 0;
    for (; i < token.size() && token[i] != 'e' && token[i] != 'E'; ++i) {
      const char c = token[i];
      if (c == '.') {
        seen_point = true;
      } else if (!seen_nonzero) {
        if (c != '0') {
          seen_nonzero = true;
          if (!seen_point) magnitude = 1;
        } else if (seen_point) {
          --magnitude;
        }
      } else if (!seen_point) {
        ++magnitude;
      }
    }
    long long exponent = 0;
    bool negative = false;
    if (i < token.size()) {
      ++i;
      if (token[i] == '+' || token[i] == '-') negative = token[i++] == '-';
      for (; i < token.size(); ++i) {
        if (exponent < 1'000'000'000) exponent = exponent * 10 + (token[i] - '0');
      }
    }
    return magnitude + (negative ? -exponent : exponent) > 0;
  }

  Node parse_name() {
    const std::size_t start = pos_;
    while (!at_end() && is_name_char(s_[pos_])) ++pos_;
    const std::string_view name = s_.substr(start, pos_ - start);
    skip_space();
    if (peek() == '(') return parse_call(name, start);
    std::optional<Node> node = resolve_ ? resolve_(name) : std::nullopt;
    if (!node) throw ExpressionError("unknown name '" + std::string(name) + "'", start);
    if (*node < 0 || static_cast<std::size_t>(*node) >= g_.size()) {
      throw ExpressionError("name '" + std::string(name) + "' resolved to a node outside the graph", start);
    }
    return *node;
  }

  Node parse_call(std::string_view name, std::size_t start) {
    const FunctionInfo* fn = nullptr;
    for (const FunctionInfo& f : kFunctions) {
      if (f.name == name) fn = &f;
    }
    if (fn == nullptr) throw ExpressionError("unknown function '" + std::string(name) + "'", start);
    DepthGuard guard(*this, pos_);
    ++pos_;  // '('
    Node args[2] = {-1, -1};
    int count = 0;
    skip_space();
    if (peek() != ')') {
      for (;;) {
        Node arg = parse_expr();
        if (count < 2) args[count] = arg;
        ++count;
        skip_space();
        if (peek() != ',') break;
        ++pos_;
      }
    }
    expect_close();
    if (count != fn->args) {
      throw ExpressionError(std::string(name) + " takes " + std::to_string(fn->args) + (fn->args == 1 ? " argument" : " arguments") +
                                ", got " + std::to_string(count),
                            start);
    }
    return fn->args == 1 ? g_.unary(fn->op, args[0]) : g_.binary(fn->op, args[0], args[1]);
  }

  Graph& g_;
  std::string_view s_;
  const Graph::Resolver& resolve_;
  std::size_t pos_ = 0;
  int depth_ = 0;
};

}  // namespace

// -----------------------------------------------------------------------------------------------------------
// Hash-consing index.

struct Graph::Impl {
  struct Key {
    Op op;
    Node a, b, c, d;
    std::uint64_t bits;
    int slot;
    bool operator==(const Key&) const = default;
  };
  struct KeyHash {
    std::size_t operator()(const Key& k) const {
      std::uint64_t h = static_cast<std::uint64_t>(k.op) * 0x9E3779B97F4A7C15ull;
      auto mix = [&h](std::uint64_t v) {
        h ^= v + 0x9E3779B97F4A7C15ull + (h << 6) + (h >> 2);
        h *= 0xBF58476D1CE4E5B9ull;
        h ^= h >> 31;
      };
      mix(static_cast<std::uint32_t>(k.a));
      mix(static_cast<std::uint32_t>(k.b));
      mix(static_cast<std::uint32_t>(k.c));
      mix(static_cast<std::uint32_t>(k.d));
      mix(k.bits);
      mix(static_cast<std::uint32_t>(k.slot));
      return static_cast<std::size_t>(h);
    }
  };
  static Key key(const Entry& e) {
    // Constants compare by bit pattern: 0.0 and -0.0 stay distinct (1/x tells them apart).
    return Key{e.op, e.a, e.b, e.c, e.d, std::bit_cast<std::uint64_t>(e.value), e.slot};
  }
  std::unordered_map<Key, Node, KeyHash> map;
};

Graph::Graph(const Graph& other) : nodes_(other.nodes_), index_(other.index_ ? std::make_shared<Impl>(*other.index_) : nullptr) {}

Graph& Graph::operator=(const Graph& other) {
  if (this != &other) {
    std::shared_ptr<Impl> index = other.index_ ? std::make_shared<Impl>(*other.index_) : nullptr;
    nodes_ = other.nodes_;
    index_ = std::move(index);
  }
  return *this;
}

Node Graph::intern(const Entry& e) {
  if (!index_) {
    // First node, or a moved-from graph being reused: index whatever nodes there are.
    index_ = std::make_shared<Impl>();
    for (std::size_t i = 0; i < nodes_.size(); ++i) index_->map.emplace(Impl::key(nodes_[i]), static_cast<Node>(i));
  }
  const Impl::Key k = Impl::key(e);
  if (auto it = index_->map.find(k); it != index_->map.end()) return it->second;
  if (nodes_.size() >= kMaxNodes) {
    throw ExpressionError("expression graph larger than " + std::to_string(kMaxNodes) + " nodes", 0);
  }
  const Node n = static_cast<Node>(nodes_.size());
  nodes_.push_back(e);
  index_->map.emplace(k, n);
  return n;
}

void Graph::check_node(Node n) const {
  if (n < 0 || static_cast<std::size_t>(n) >= nodes_.size()) {
    throw std::out_of_range("expression node " + std::to_string(n) + " is not in this graph");
  }
}

std::size_t Graph::size() const { return nodes_.size(); }

const Graph::Entry& Graph::entry(Node n) const {
  check_node(n);
  return nodes_[static_cast<std::size_t>(n)];
}

Node Graph::constant(double value) {
  Entry e{Op::kConst};
  e.value = value;
  return intern(e);
}

Node Graph::variable(int slot) {
  if (slot < 0) throw std::invalid_argument("variable slot must be >= 0, got " + std::to_string(slot));
  Entry e{Op::kVar};
  e.slot = slot;
  return intern(e);
}

// -----------------------------------------------------------------------------------------------------------
// Simplifying builders. Only rewrites that are exact in IEEE arithmetic for finite values are applied, plus
// the identities the interface promises (x*0 = 0 and 0/x = 0 ignore inf/NaN in x on purpose: they are what
// makes the derivative of a constant come out as the constant 0).

Node Graph::unary(Op op, Node a) {
  check_node(a);
  if (arity(op) != 1) throw std::invalid_argument("Graph::unary called with a non-unary operator");
  const Entry ea = nodes_[static_cast<std::size_t>(a)];  // a copy: interning may reallocate nodes_
  if (ea.op == Op::kConst) return constant(apply(op, ea.value, 0.0, 0.0, 0.0));
  switch (op) {
    case Op::kNeg:
      if (ea.op == Op::kNeg) return ea.a;  // -(-x) = x
      // -(c*x) = (-c)*x: negation is exact, and it lets c*(-sin x) and -(c*sin x) share one node.
      if (ea.op == Op::kMul && nodes_[static_cast<std::size_t>(ea.a)].op == Op::kConst) {
        return binary(Op::kMul, constant(-nodes_[static_cast<std::size_t>(ea.a)].value), ea.b);
      }
      break;
    case Op::kAbs:
      if (ea.op == Op::kNeg || ea.op == Op::kAbs) return unary(Op::kAbs, ea.a);
      if (ea.op == Op::kSquare) return a;
      break;
    default: break;
  }
  Entry e{op, a};
  return intern(e);
}

Node Graph::binary(Op op, Node a, Node b) {
  check_node(a);
  check_node(b);
  if (arity(op) != 2) throw std::invalid_argument("Graph::binary called with a non-binary operator");
  auto is_const = [this](Node n) { return nodes_[static_cast<std::size_t>(n)].op == Op::kConst; };
  auto is_value = [&](Node n, double v) { return is_const(n) && nodes_[static_cast<std::size_t>(n)].value == v; };
  auto op_of = [this](Node n) { return nodes_[static_cast<std::size_t>(n)].op; };
  auto arg_of = [this](Node n) { return nodes_[static_cast<std::size_t>(n)].a; };

  if (is_const(a) && is_const(b)) {
    return constant(apply(op, nodes_[static_cast<std::size_t>(a)].value, nodes_[static_cast<std::size_t>(b)].value, 0.0, 0.0));
  }
  // IEEE addition and multiplication are commutative, so a canonical operand order (constant first, then
  // by index) is exact and lets a*b and b*a share one node.
  if (is_commutative(op) && (is_const(b) || (!is_const(a) && b < a))) std::swap(a, b);

  switch (op) {
    case Op::kAdd:
      if (is_value(a, 0.0)) return b;                                   // 0 + x
      if (op_of(b) == Op::kNeg) return binary(Op::kSub, a, arg_of(b));  // a + (-y) = a - y
      if (op_of(a) == Op::kNeg) return binary(Op::kSub, b, arg_of(a));  // (-y) + b = b - y
      break;
    case Op::kSub:
      if (a == b) return constant(0.0);                                 // x - x
      if (is_value(b, 0.0)) return a;                                   // x - 0
      if (is_value(a, 0.0)) return unary(Op::kNeg, b);                  // 0 - x
      if (op_of(b) == Op::kNeg) return binary(Op::kAdd, a, arg_of(b));  // a - (-y) = a + y
      break;
    case Op::kMul:
      if (is_const(a)) {
        const double c = nodes_[static_cast<std::size_t>(a)].value;
        if (c == 0.0) return constant(0.0);                                          // 0 * x
        if (c == 1.0) return b;                                                      // 1 * x
        if (c == -1.0) return unary(Op::kNeg, b);                                    // -1 * x
        if (op_of(b) == Op::kNeg) return binary(Op::kMul, constant(-c), arg_of(b));  // c*(-y) = (-c)*y
      } else if (op_of(a) == Op::kNeg && op_of(b) == Op::kNeg) {
        return binary(Op::kMul, arg_of(a), arg_of(b));  // (-x)*(-y) = x*y
      }
      break;
    case Op::kDiv:
      if (is_value(b, 1.0)) return a;                    // x / 1
      if (is_value(b, -1.0)) return unary(Op::kNeg, a);  // x / -1
      if (is_value(a, 0.0)) return constant(0.0);        // 0 / x
      break;
    case Op::kPow:
      if (is_value(b, 0.0)) return constant(1.0);          // x^0
      if (is_value(b, 1.0)) return a;                      // x^1
      if (is_value(b, 2.0)) return unary(Op::kSquare, a);  // x^2
      if (is_value(a, 1.0)) return constant(1.0);          // 1^y (= 1 in IEEE, even for NaN)
      break;
    case Op::kMin:
    case Op::kMax:
      if (a == b) return a;
      break;
    default: break;
  }
  Entry e{op, a, b};
  return intern(e);
}

Node Graph::select_le(Node a, Node b, Node c, Node d) {
  if (c == d) return c;
  const Entry& ea = nodes_[static_cast<std::size_t>(a)];
  const Entry& eb = nodes_[static_cast<std::size_t>(b)];
  if (ea.op == Op::kConst && eb.op == Op::kConst) return select_le_of(ea.value, eb.value, 1.0, 0.0) != 0.0 ? c : d;
  Entry e{Op::kSelectLe, a, b};
  e.c = c;
  e.d = d;
  return intern(e);
}

// -----------------------------------------------------------------------------------------------------------
// Parsing and queries.

Node Graph::parse(std::string_view text, const Resolver& resolve) { return Parser(*this, text, resolve).parse(); }

namespace {

// Calls visit(n) once for every node reachable from `root` and not yet `done`, children before parents,
// without recursion (derivatives of long sums are thousands of levels deep).
template <typename Visit>
void post_order(const Graph& graph, Node root, std::vector<char>& done, Visit&& visit) {
  std::vector<std::pair<Node, bool>> stack{{root, false}};
  while (!stack.empty()) {
    auto [n, expanded] = stack.back();
    stack.pop_back();
    if (done[static_cast<std::size_t>(n)]) continue;
    if (expanded) {
      done[static_cast<std::size_t>(n)] = 1;
      visit(n);
      continue;
    }
    stack.push_back({n, true});
    const Graph::Entry& e = graph.entry(n);
    for (Node child : {e.d, e.c, e.b, e.a}) {
      if (child >= 0 && !done[static_cast<std::size_t>(child)]) stack.push_back({child, false});
    }
  }
}

}  // namespace

bool Graph::any_reachable(Node f, const std::function<bool(const Entry&)>& found) const {
  check_node(f);
  std::vector<char> seen(nodes_.size(), 0);
  std::vector<Node> stack{f};
  seen[static_cast<std::size_t>(f)] = 1;
  while (!stack.empty()) {
    const Entry& e = nodes_[static_cast<std::size_t>(stack.back())];
    stack.pop_back();
    if (found(e)) return true;
    for (Node child : {e.a, e.b, e.c, e.d}) {
      if (child >= 0 && !seen[static_cast<std::size_t>(child)]) {
        seen[static_cast<std::size_t>(child)] = 1;
        stack.push_back(child);
      }
    }
  }
  return false;
}

bool Graph::depends_on(Node f, int slot) const {
  return any_reachable(f, [slot](const Entry& e) { return e.op == Op::kVar && e.slot == slot; });
}

bool Graph::smooth_everywhere(Node f) const {
  // True unless some reachable operation is smooth only on a domain, or not smooth.
  return !any_reachable(f, [this](const Entry& e) {
    switch (e.op) {
      case Op::kConst:
      case Op::kVar:
      case Op::kAdd:
      case Op::kSub:
      case Op::kMul:
      case Op::kNeg:
      case Op::kSin:
      case Op::kCos:
      case Op::kAtan:
      case Op::kSinh:
      case Op::kCosh:
      case Op::kTanh:
      case Op::kExp:
      case Op::kSquare: return false;
      case Op::kPow: {  // smooth for a constant non-negative integer exponent only
        const Entry& exponent = nodes_[static_cast<std::size_t>(e.b)];
        return exponent.op != Op::kConst || !(exponent.value >= 0.0) || exponent.value != std::floor(exponent.value);
      }
      default: return true;
    }
  });
}

// Every builder folds operators whose operands are all constant, so a node without any variable below it
// is always a kConst node.
bool Graph::is_constant(Node f) const { return entry(f).op == Op::kConst; }

double Graph::constant_value(Node f) const {
  const Entry& e = entry(f);
  if (e.op != Op::kConst) throw std::logic_error("constant_value of a non-constant expression");
  return e.value;
}

std::string Graph::to_string(Node f) const { return to_string(f, SlotNamer{}); }

std::string Graph::to_string(Node f, const SlotNamer& slot_name) const {
  check_node(f);
  // Shared subexpressions are printed once per use, so the text of a DAG can be exponentially longer than
  // the DAG; it is cut off, since the result is only for humans.
  constexpr std::size_t kMaxOutput = 1 << 20;
  struct Item {
    Node node;         // expanded if text == nullptr
    const char* text;  // literal piece
  };
  std::string out;
  std::vector<Item> stack{{f, nullptr}};
  auto push_text = [&stack](const char* t) { stack.push_back({-1, t}); };
  auto push_node = [&stack](Node n) { stack.push_back({n, nullptr}); };
  while (!stack.empty()) {
    if (out.size() > kMaxOutput) {
      out += "...";
      break;
    }
    const Item item = stack.back();
    stack.pop_back();
    if (item.text != nullptr) {
      out += item.text;
      continue;
    }
    const Entry& e = nodes_[static_cast<std::size_t>(item.node)];
    // Pieces are pushed in reverse order of output.
    switch (e.op) {
      case Op::kConst:
        // Negative constants in parentheses, so that the text reads back the same way ("x-(-2)").
        // Appended piece by piece: `"(" + std::string` trips a false -Wrestrict in GCC 12 at -O3.
        if (std::signbit(e.value) && !std::isnan(e.value)) {
          out += '(';
          out += platform::shortest(e.value);  // the shortest text that reads back exactly
          out += ')';
        } else {
          out += platform::shortest(e.value);
        }
        break;
      case Op::kVar:
        if (slot_name) {
          out += slot_name(e.slot);
        } else {
          out += 'x';
          out += std::to_string(e.slot);
        }
        break;
      case Op::kAdd:
      case Op::kSub:
      case Op::kMul:
      case Op::kDiv:
      case Op::kPow: {
        static constexpr const char* kInfix[] = {"+", "-", "*", "/", "^"};
        push_text(")");
        push_node(e.b);
        push_text(kInfix[static_cast<int>(e.op) - static_cast<int>(Op::kAdd)]);
        push_node(e.a);
        push_text("(");
        break;
      }
      case Op::kNeg:
        push_text(")");
        push_node(e.a);
        push_text("(-");
        break;
      case Op::kSquare:
        push_text("^2)");
        push_node(e.a);
        push_text("(");
        break;
      case Op::kSelectLe:
        push_text(")");
        push_node(e.d);
        push_text(" : ");
        push_node(e.c);
        push_text(" ? ");
        push_node(e.b);
        push_text(" <= ");
        push_node(e.a);
        push_text("(");
        break;
      default: {
        const char* name = function_name(e.op);
        out += name != nullptr ? name : "?";
        push_text(")");
        if (e.b >= 0) {
          push_node(e.b);
          push_text(", ");
        }
        push_node(e.a);
        push_text("(");
        break;
      }
    }
  }
  return out;
}

// -----------------------------------------------------------------------------------------------------------
// Symbolic differentiation. Nodes are visited children-first; a node that does not reach the variable gets
// derivative 0 without applying any rule, and every rule goes through the simplifying builders, so
// derivatives of constants are the constant 0 (callers use is_constant on them, e.g. to detect a constant
// mass matrix).

Node Graph::derivative(Node f, int slot) {
  check_node(f);
  const Node zero = constant(0.0);
  const Node one = constant(1.0);

  // Reachable nodes in post-order, and for each whether it reaches the variable.
  std::vector<Node> order;
  {
    std::vector<char> done(nodes_.size(), 0);
    post_order(*this, f, done, [&order](Node n) { order.push_back(n); });
  }
  std::unordered_map<Node, Node> d;  // node -> its derivative; absent = does not depend on the variable
  d.reserve(order.size());
  auto dn = [&d, zero](Node n) {
    auto it = d.find(n);
    return it == d.end() ? zero : it->second;
  };
  auto depends = [&d](Node n) { return n >= 0 && d.count(n) != 0; };

  for (Node n : order) {
    const Entry e = nodes_[static_cast<std::size_t>(n)];  // a copy: the builders below may reallocate nodes_
    if (e.op == Op::kVar) {
      if (e.slot == slot) d.emplace(n, one);
      continue;
    }
    if (e.op == Op::kConst || !(depends(e.a) || depends(e.b) || depends(e.c) || depends(e.d))) continue;

    const Node u = e.a, v = e.b;
    const Node du = dn(e.a);
    const Node dv = e.b >= 0 ? dn(e.b) : zero;
    auto add = [this](Node x, Node y) { return binary(Op::kAdd, x, y); };
    auto sub = [this](Node x, Node y) { return binary(Op::kSub, x, y); };
    auto mul = [this](Node x, Node y) { return binary(Op::kMul, x, y); };
    auto div = [this](Node x, Node y) { return binary(Op::kDiv, x, y); };
    auto neg = [this](Node x) { return unary(Op::kNeg, x); };
    auto sq = [this](Node x) { return unary(Op::kSquare, x); };
    auto sqrt_ = [this](Node x) { return unary(Op::kSqrt, x); };

    Node r = zero;
    switch (e.op) {
      case Op::kConst:
      case Op::kVar: break;
      case Op::kAdd: r = add(du, dv); break;
      case Op::kSub: r = sub(du, dv); break;
      case Op::kMul: r = add(mul(du, v), mul(u, dv)); break;
      case Op::kDiv: r = div(sub(du, mul(n, dv)), v); break;  // (u/v)' = (u' - (u/v) v') / v
      case Op::kPow:
        if (!depends(v)) {
          // u^c: c u^(c-1) u'. The exponent need not be a literal, only independent of the variable.
          r = mul(mul(v, binary(Op::kPow, u, sub(v, one))), du);
        } else if (!depends(u)) {
          r = mul(mul(n, unary(Op::kLog, u)), dv);  // (c^v)' = c^v log(c) v'
        } else {
          r = mul(n, add(mul(dv, unary(Op::kLog, u)), div(mul(v, du), u)));
        }
        break;
      case Op::kNeg: r = neg(du); break;
      case Op::kSin: r = mul(unary(Op::kCos, u), du); break;
      case Op::kCos: r = mul(neg(unary(Op::kSin, u)), du); break;
      case Op::kTan: r = mul(add(one, sq(n)), du); break;
      case Op::kAsin: r = div(du, sqrt_(sub(one, sq(u)))); break;
      case Op::kAcos: r = neg(div(du, sqrt_(sub(one, sq(u))))); break;
      case Op::kAtan: r = div(du, add(one, sq(u))); break;
      case Op::kAtan2: r = div(sub(mul(v, du), mul(u, dv)), add(sq(v), sq(u))); break;  // atan2(u=y, v=x)
      case Op::kSinh: r = mul(unary(Op::kCosh, u), du); break;
      case Op::kCosh: r = mul(unary(Op::kSinh, u), du); break;
      case Op::kTanh: r = mul(sub(one, sq(n)), du); break;
      case Op::kExp: r = mul(n, du); break;
      case Op::kLog: r = div(du, u); break;
      case Op::kSqrt: r = div(du, mul(constant(2.0), n)); break;
      case Op::kAbs: r = mul(unary(Op::kSign, u), du); break;
      case Op::kSign: r = zero; break;
      case Op::kSquare: r = mul(mul(constant(2.0), u), du); break;
      // min picks u unless v < u; the derivative follows the same choice (ties: the first argument).
      case Op::kMin: r = select_le(u, v, du, dv); break;
      // max picks u unless u < v, i.e. the choice select_le(v, u, ...) makes.
      case Op::kMax: r = select_le(v, u, du, dv); break;
      case Op::kSelectLe: r = select_le(e.a, e.b, dn(e.c), dn(e.d)); break;
      case Op::kSinCos: break;  // never in a graph
    }
    d.emplace(n, r);
  }
  return dn(f);
}

// -----------------------------------------------------------------------------------------------------------
// Tape.

Tape Tape::compile(const Graph& graph, const std::vector<Node>& outputs, int num_slots, int num_params) {
  Tape tape;
  tape.num_params_ = num_params;
  // Every node the outputs reach, children before parents, each once.
  std::vector<Node> order;
  {
    std::vector<char> done(graph.size(), 0);
    for (Node out : outputs) {
      graph.entry(out);  // range check
      post_order(graph, out, done, [&order](Node n) { order.push_back(n); });
    }
  }
  // Bound nodes: constants, parameters, and what depends on them alone (computed by bind()).
  std::vector<char> bound(graph.size(), 0);
  for (Node n : order) {
    const Graph::Entry& e = graph.entry(n);
    if (e.op == Op::kVar) {
      if (e.slot >= num_slots + num_params) {
        throw std::invalid_argument("expression uses input slot " + std::to_string(e.slot) + " but the tape has " +
                                    std::to_string(num_slots) + " inputs and " + std::to_string(num_params) + " parameters");
      }
      bound[static_cast<std::size_t>(n)] = e.slot >= num_slots;
    } else {
      auto is_bound = [&bound](Node c) { return c < 0 || bound[static_cast<std::size_t>(c)]; };
      bound[static_cast<std::size_t>(n)] = e.op == Op::kConst || (is_bound(e.a) && is_bound(e.b) && is_bound(e.c) && is_bound(e.d));
    }
  }

  // The entries as the tape computes them. The graph rewrites -(c*x) to (-c)*x and c*(-y) to (-c)*y when
  // c is a constant (Graph::unary, Graph::binary); here the same is done for a bound c (a parameter or a
  // node of them), with -c a bound node of its own (node number graph.size() + i, computed by bind()), so
  // that a bound tape has no more instructions than the tape with the parameters folded in. Both forms
  // give the same bits: negation is exact and rounding is symmetric about 0.
  const auto first_added = static_cast<Node>(graph.size());
  std::vector<Graph::Entry> entries(graph.size(), Graph::Entry{Op::kConst});
  for (Node n : order) entries[static_cast<std::size_t>(n)] = graph.entry(n);
  std::vector<int> uses(graph.size(), 0);
  for (Node n : order) {
    const Graph::Entry& e = entries[static_cast<std::size_t>(n)];
    for (Node c : {e.a, e.b, e.c, e.d})
      if (c >= 0) ++uses[static_cast<std::size_t>(c)];
  }
  for (Node out : outputs) ++uses[static_cast<std::size_t>(out)];
  std::vector<Graph::Entry> added;          // -c for a bound c
  std::unordered_map<Node, Node> negation;  // c -> -c, the graph's own node where it has one
  for (Node n : order)
    if (bound[static_cast<std::size_t>(n)] && entries[static_cast<std::size_t>(n)].op == Op::kNeg)
      negation.emplace(entries[static_cast<std::size_t>(n)].a, n);
  auto negation_of = [&](Node c) {
    // -(-u) = u
    const Graph::Entry& ec = c < first_added ? entries[static_cast<std::size_t>(c)] : added[static_cast<std::size_t>(c - first_added)];
    if (ec.op == Op::kNeg) return ec.a;
    const auto [it, inserted] = negation.try_emplace(c, first_added + static_cast<Node>(added.size()));
    if (inserted) added.push_back(Graph::Entry{Op::kNeg, c});
    return it->second;
  };
  auto is_bound = [&](Node x) { return x >= first_added || bound[static_cast<std::size_t>(x)]; };
  auto bound_alone = [&](Node x, Node y) { return is_bound(x) && !is_bound(y); };
  // A rewrite makes n use x (n's operands change); when the node it used instead is then used by nothing,
  // that node is not emitted, and no longer uses its own operands.
  auto rewrite = [&](Graph::Entry& e, Node replaced, Node c, Node x) {
    ++uses[static_cast<std::size_t>(x)];
    if (--uses[static_cast<std::size_t>(replaced)] == 0) {
      const Graph::Entry& r = entries[static_cast<std::size_t>(replaced)];
      for (Node k : {r.a, r.b})
        if (k >= 0 && k < first_added) --uses[static_cast<std::size_t>(k)];
    }
    e = Graph::Entry{Op::kMul, negation_of(c), x};
  };
  // Rewritten nodes can equal other nodes ((-c)*x made from -(c*x) and from c*(-x)): each is computed
  // once, by the first of them (alias), as the graph shares equal nodes.
  std::vector<Node> alias(graph.size());
  std::iota(alias.begin(), alias.end(), Node{0});
  auto canonical = [&](Node k) { return k >= 0 && k < first_added ? alias[static_cast<std::size_t>(k)] : k; };
  struct Key {
    Op op;
    Node a, b, c, d;
    bool operator==(const Key&) const = default;
  };
  struct KeyHash {
    std::size_t operator()(const Key& k) const {
      std::size_t h = static_cast<std::size_t>(k.op);
      for (Node x : {k.a, k.b, k.c, k.d}) h = h * 1000003u ^ static_cast<std::size_t>(x + 1);
      return h;
    }
  };
  std::unordered_map<Key, Node, KeyHash> computed;
  for (Node n : order) {
    if (bound[static_cast<std::size_t>(n)]) continue;
    Graph::Entry& e = entries[static_cast<std::size_t>(n)];
    for (Node* k : {&e.a, &e.b, &e.c, &e.d}) *k = canonical(*k);
    if (e.op == Op::kVar) continue;
    if (e.op == Op::kNeg) {
      // -(c*x) -> (-c)*x
      const Graph::Entry m = entries[static_cast<std::size_t>(e.a)];
      const Node c = m.op != Op::kMul ? -1 : bound_alone(m.a, m.b) ? m.a : bound_alone(m.b, m.a) ? m.b : -1;
      if (c >= 0) rewrite(e, e.a, c, c == m.a ? m.b : m.a);
    } else if (e.op == Op::kMul) {
      // c*(-y) -> (-c)*y
      for (const auto& [c, other] : {std::pair{e.a, e.b}, std::pair{e.b, e.a}}) {
        if (!bound_alone(c, other)) continue;
        const Graph::Entry o = entries[static_cast<std::size_t>(other)];
        if (o.op == Op::kNeg) rewrite(e, other, c, o.a);
        break;
      }
    }
    Key key{e.op, e.a, e.b, e.c, e.d};
    if (is_commutative(e.op) && key.b < key.a) std::swap(key.a, key.b);
    const auto [it, first] = computed.try_emplace(key, n);
    if (first) continue;
    if (uses[static_cast<std::size_t>(it->second)] == 0) {  // that node was rewritten away: n computes it
      it->second = n;
      continue;
    }
    // Computed already: n's users use that node instead, and n no longer uses its operands.
    alias[static_cast<std::size_t>(n)] = it->second;
    uses[static_cast<std::size_t>(it->second)] += uses[static_cast<std::size_t>(n)];
    uses[static_cast<std::size_t>(n)] = 0;
    for (Node k : {e.a, e.b, e.c, e.d})
      if (k >= 0 && k < first_added) --uses[static_cast<std::size_t>(k)];
  }
  auto entry_of = [&](Node n) -> const Graph::Entry& {
    return n < first_added ? entries[static_cast<std::size_t>(n)] : added[static_cast<std::size_t>(n - first_added)];
  };
  std::vector<Node> bound_order;  // the bound nodes in an order bind() can compute them in
  for (Node n : order)
    if (bound[static_cast<std::size_t>(n)]) bound_order.push_back(n);
  for (std::size_t i = 0; i < added.size(); ++i) bound_order.push_back(first_added + static_cast<Node>(i));

  std::vector<std::int32_t> reg(graph.size() + added.size(), -1);
  auto reg_of = [&reg](Node n) { return n >= 0 ? reg[static_cast<std::size_t>(n)] : -1; };

  // Leaves get the first registers: the bound nodes, then the inputs. Of the bound nodes, those eval()
  // reads (operands of instructions, outputs) come first, since it copies them into the scratch at every
  // call; those only bind() reads (a parameter used only in a product of parameters) come after them.
  std::vector<char> read(reg.size(), 0);
  for (Node n : order) {
    if (bound[static_cast<std::size_t>(n)] || uses[static_cast<std::size_t>(n)] == 0) continue;
    const Graph::Entry& e = entries[static_cast<std::size_t>(n)];
    for (Node k : {e.a, e.b, e.c, e.d})
      if (k >= 0 && is_bound(k)) read[static_cast<std::size_t>(k)] = 1;
  }
  for (Node out : outputs)
    if (is_bound(canonical(out))) read[static_cast<std::size_t>(canonical(out))] = 1;
  const double unset = std::numeric_limits<double>::quiet_NaN();
  for (const bool read_by_eval : {true, false}) {
    for (Node n : bound_order) {
      if (static_cast<bool>(read[static_cast<std::size_t>(n)]) != read_by_eval) continue;
      const Graph::Entry& e = entry_of(n);
      reg[static_cast<std::size_t>(n)] = static_cast<std::int32_t>(tape.constants_.size());
      tape.constants_.push_back(e.op == Op::kConst ? e.value : unset);
    }
    if (read_by_eval) tape.num_read_constants_ = tape.constants_.size();
  }
  for (Node n : bound_order) {
    const Graph::Entry& e = entry_of(n);
    if (e.op == Op::kVar) tape.param_regs_.emplace_back(reg_of(n), e.slot - num_slots);
    if (e.op != Op::kVar && e.op != Op::kConst)
      tape.bind_code_.push_back(BoundInstr{e.op, reg_of(e.a), reg_of(e.b), reg_of(e.c), reg_of(e.d), reg_of(n)});
  }
  for (Node n : order) {
    const Graph::Entry& e = entries[static_cast<std::size_t>(n)];
    if (e.op != Op::kVar || bound[static_cast<std::size_t>(n)]) continue;
    reg[static_cast<std::size_t>(n)] = static_cast<std::int32_t>(tape.constants_.size() + tape.input_slots_.size());
    tape.input_slots_.push_back(e.slot);
  }
  tape.first_instr_reg_ = tape.constants_.size() + tape.input_slots_.size();

  // sin(u) and cos(u) both needed: mechanical models are full of them (rotations), and one fused
  // instruction shares the argument reduction between the two.
  std::unordered_map<Node, std::pair<Node, Node>> trig;  // u -> (sin(u), cos(u))
  for (Node n : order) {
    const Graph::Entry& e = entries[static_cast<std::size_t>(n)];
    if (uses[static_cast<std::size_t>(n)] == 0) continue;
    if (e.op == Op::kSin || e.op == Op::kCos) {
      auto [it, inserted] = trig.try_emplace(e.a, -1, -1);
      (e.op == Op::kSin ? it->second.first : it->second.second) = n;
    }
  }

  auto emit = [&](Node n, const Instr& in) {
    reg[static_cast<std::size_t>(n)] = static_cast<std::int32_t>(tape.first_instr_reg_ + tape.code_.size());
    tape.code_.push_back(in);
  };
  for (Node n : order) {
    if (reg[static_cast<std::size_t>(n)] >= 0) continue;   // a leaf, or the cos half of a fused pair
    if (uses[static_cast<std::size_t>(n)] == 0) continue;  // rewritten away, or computed by another node
    const Graph::Entry& e = entries[static_cast<std::size_t>(n)];
    if (e.op == Op::kSin || e.op == Op::kCos) {
      const auto [sin_node, cos_node] = trig.at(e.a);
      if (sin_node >= 0 && cos_node >= 0) {
        emit(sin_node, Instr{Op::kSinCos, reg_of(e.a), -1, -1, -1, 0.0});
        // Never executed (kSinCos skips it), but keeps instruction i <-> register first + i.
        emit(cos_node, Instr{Op::kCos, reg_of(e.a), -1, -1, -1, 0.0});
        continue;
      }
    }
    emit(n, Instr{e.op, reg_of(e.a), reg_of(e.b), reg_of(e.c), reg_of(e.d), 0.0});
  }
  for (Node out : outputs) tape.output_regs_.push_back(reg[static_cast<std::size_t>(canonical(out))]);
  tape.scratch_size_ = tape.first_instr_reg_ + tape.code_.size();
  // x^p with p bound: the graph rewrites x^2 to x*x when the exponent is the constant 2, so bind() does
  // the same when p is 2 (pow(x, 2) need not round as x*x does).
  if (!tape.bind_code_.empty() || !tape.param_regs_.empty())
    for (std::size_t i = 0; i < tape.code_.size(); ++i)
      if (tape.code_[i].op == Op::kPow && tape.code_[i].b >= 0 && static_cast<std::size_t>(tape.code_[i].b) < tape.constants_.size())
        tape.pow_of_bound_.push_back(static_cast<std::int32_t>(i));
  tape.native_ = compile_native(tape, nullptr, nullptr);
  tape.native_run_ = tape.native_ ? tape.native_->run : nullptr;
  return tape;
}

bool Tape::bind(const double* params) {
  bool generic = true;
  for (const auto& [r, k] : param_regs_) {
    constants_[static_cast<std::size_t>(r)] = params[k];
    generic = generic && params[k] != 0.0;
  }
  const double* c = constants_.data();
  auto at = [c](std::int32_t r) { return r >= 0 ? c[r] : 0.0; };
  for (const BoundInstr& in : bind_code_) {
    const double v = apply(in.op, at(in.a), at(in.b), at(in.c), at(in.d));
    constants_[static_cast<std::size_t>(in.target)] = v;
    generic = generic && v != 0.0;
  }
  for (std::int32_t i : pow_of_bound_) {
    Instr& in = code_[static_cast<std::size_t>(i)];
    in.op = c[in.b] == 2.0 ? Op::kSquare : Op::kPow;
  }
  return generic;
}

void Tape::load_constants(double* scratch) const {
  const double* constants = constants_.data();
  for (std::size_t k = 0; k < num_read_constants_; ++k) scratch[k] = constants[k];
}

std::int32_t Tape::input_register(int slot) const {
  for (std::size_t k = 0; k < input_slots_.size(); ++k)
    if (input_slots_[k] == slot) return static_cast<std::int32_t>(constants_.size() + k);
  return -1;
}

void Tape::eval(const double* slots, double* outputs, double* scratch) const {
  load_constants(scratch);
  const std::int32_t* inputs = input_slots_.data();
  double* input_regs = scratch + constants_.size();
  for (std::size_t k = 0, m = input_slots_.size(); k < m; ++k) input_regs[k] = slots[inputs[k]];
  run(scratch);
  const std::int32_t* regs = output_regs_.data();
  for (std::size_t j = 0, m = output_regs_.size(); j < m; ++j) outputs[j] = scratch[regs[j]];
}

void Tape::wire(const Wiring& wiring) {
  std::vector<Wire> inputs, outputs;
  for (std::size_t k = 0; k < input_slots_.size(); ++k) {
    const auto slot = static_cast<std::size_t>(input_slots_[k]);
    if (slot >= wiring.inputs.size() || wiring.inputs[slot].array < 0)
      throw std::invalid_argument("the tape reads input slot " + std::to_string(slot) + ", which the wiring does not place");
    inputs.push_back({static_cast<std::int32_t>(constants_.size() + k), wiring.inputs[slot].array, wiring.inputs[slot].index});
  }
  if (wiring.outputs.size() < output_regs_.size())
    throw std::invalid_argument("the wiring places " + std::to_string(wiring.outputs.size()) + " outputs of " +
                                std::to_string(output_regs_.size()));
  for (std::size_t j = 0; j < output_regs_.size(); ++j)
    for (const Place& p : wiring.outputs[j]) outputs.push_back({output_regs_[j], p.array, p.index});
  wired_inputs_ = std::move(inputs);
  wired_outputs_ = std::move(outputs);
  wired_native_ = compile_native(*this, &wired_inputs_, &wired_outputs_);
  native_run_wired_ = wired_native_ ? wired_native_->run_wired : nullptr;
}

void Tape::run_wired_interpreted(double* scratch, const double* const* sources, double* const* sinks) const {
  for (const Wire& w : wired_inputs_) scratch[w.reg] = sources[w.array][w.index];
  run_interpreted(scratch);
  for (const Wire& w : wired_outputs_) sinks[w.array][w.index] = scratch[w.reg];
}

void Tape::run_interpreted(double* scratch) const {
  double* s = scratch;
  double* r = s + first_instr_reg_;
  const Instr* code = code_.data();
  const std::size_t n = code_.size();
  for (std::size_t i = 0; i < n; ++i) {
    const Instr& in = code[i];
    double v;
    switch (in.op) {
      case Op::kAdd: v = s[in.a] + s[in.b]; break;
      case Op::kSub: v = s[in.a] - s[in.b]; break;
      case Op::kMul: v = s[in.a] * s[in.b]; break;
      case Op::kDiv: v = s[in.a] / s[in.b]; break;
      case Op::kPow: v = std::pow(s[in.a], s[in.b]); break;
      case Op::kNeg: v = -s[in.a]; break;
      case Op::kSin: v = std::sin(s[in.a]); break;
      case Op::kCos: v = std::cos(s[in.a]); break;
      case Op::kTan: v = std::tan(s[in.a]); break;
      case Op::kAsin: v = std::asin(s[in.a]); break;
      case Op::kAcos: v = std::acos(s[in.a]); break;
      case Op::kAtan: v = std::atan(s[in.a]); break;
      case Op::kAtan2: v = std::atan2(s[in.a], s[in.b]); break;
      case Op::kSinh: v = std::sinh(s[in.a]); break;
      case Op::kCosh: v = std::cosh(s[in.a]); break;
      case Op::kTanh: v = std::tanh(s[in.a]); break;
      case Op::kExp: v = std::exp(s[in.a]); break;
      case Op::kLog: v = std::log(s[in.a]); break;
      case Op::kSqrt: v = std::sqrt(s[in.a]); break;
      case Op::kAbs: v = std::fabs(s[in.a]); break;
      case Op::kMin: v = min_of(s[in.a], s[in.b]); break;
      case Op::kMax: v = max_of(s[in.a], s[in.b]); break;
      case Op::kSign: v = sign_of(s[in.a]); break;
      case Op::kSquare: v = s[in.a] * s[in.a]; break;
      case Op::kSelectLe: v = select_le_of(s[in.a], s[in.b], s[in.c], s[in.d]); break;
      case Op::kSinCos: {
        const double x = s[in.a];
#if defined(__GLIBC__)
        // One call, one argument reduction. glibc's sincos computes exactly what sin and cos compute
        // (the tests check it), so constant folding and the tape still agree bit for bit.
        ::sincos(x, &r[i], &r[i + 1]);
#else
        r[i] = std::sin(x);
        r[i + 1] = std::cos(x);
#endif
        ++i;
        continue;
      }
      case Op::kConst:
      case Op::kVar:
      default: __builtin_unreachable();  // leaves are not instructions; lets the switch skip its range check
    }
    r[i] = v;
  }
}

}  // namespace moreau::expr

// Expressions of the scene format: parsed once into a hash-consed DAG, differentiated symbolically
// (exact derivatives, never finite differences), and compiled into a Tape that evaluates many outputs in
// one pass without allocating.
//
// Grammar (precedence from low to high; ^ is right-associative and binds tighter than unary minus, so
// -x^2 == -(x^2)):
//   expr    := term (('+' | '-') term)*
//   term    := unary (('*' | '/') unary)*
//   unary   := ('-' | '+') unary | power
//   power   := primary ('^' unary)?
//   primary := number | name | name '(' expr (',' expr)* ')' | '(' expr ')'
// Functions: sin cos tan asin acos atan atan2 sinh cosh tanh exp log sqrt abs min max pow.
// Names are resolved by the caller (parameters, coordinates, velocities, t).
//
// Limits (documented in docs/scene-format.md): text length kMaxTextLength, nesting depth kMaxDepth, nodes
// per graph kMaxNodes. Exceeding one is an ExpressionError, never a crash or unbounded work.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace moreau::expr {

inline constexpr std::size_t kMaxTextLength = 16384;
inline constexpr int kMaxDepth = 128;
inline constexpr std::size_t kMaxNodes = 1'000'000;

// A parse or limit error. `position` is the 0-based character offset in the text the error is about.
class ExpressionError : public std::runtime_error {
 public:
  ExpressionError(const std::string& message, std::size_t position) : std::runtime_error(message), position_(position) {}
  std::size_t position() const { return position_; }

 private:
  std::size_t position_;
};

enum class Op : std::uint8_t {
  kConst,
  kVar,
  kAdd,
  kSub,
  kMul,
  kDiv,
  kPow,
  kNeg,
  kSin,
  kCos,
  kTan,
  kAsin,
  kAcos,
  kAtan,
  kAtan2,
  kSinh,
  kCosh,
  kTanh,
  kExp,
  kLog,
  kSqrt,
  kAbs,
  kMin,
  kMax,
  kSign,      // internal: derivative of abs; sign(0) = 0
  kSquare,    // internal: x*x, from x^2
  kSelectLe,  // internal: (a <= b) ? c : d, with the tie/NaN behaviour of std::min; derivative of min/max
  kSinCos,    // tape only: sin(a) into the instruction's register and cos(a) into the next; never in a Graph
};

// Index of a node in a Graph.
using Node = std::int32_t;

// A DAG of expression nodes. Structurally equal nodes are shared (hash-consing), so common
// subexpressions are computed once by a Tape. Builders fold constants and simplify the trivial
// identities (x+0, x*1, x*0, x-x, --x, x^1, x^0, x^2 -> square).
class Graph {
 public:
  // Resolves a name to a node (a variable or a constant), or nullopt if unknown.
  using Resolver = std::function<std::optional<Node>(std::string_view name)>;
  // Names a variable slot in to_string; the default spelling is "x<slot>".
  using SlotNamer = std::function<std::string(int slot)>;

  // Copies get their own hash-consing index: a shared index would hand out node indices that are
  // only valid in the other graph.
  Graph() = default;
  Graph(const Graph& other);
  Graph& operator=(const Graph& other);
  Graph(Graph&&) noexcept = default;
  Graph& operator=(Graph&&) noexcept = default;
  ~Graph() = default;

  Node constant(double value);
  Node variable(int slot);  // slot >= 0: an index into the inputs of Tape::eval

  // Parses `text`. Throws ExpressionError (with the offset) on syntax errors, unknown names
  // ("unknown name 'foo'"), unknown functions, wrong argument counts, non-finite literals and limits.
  Node parse(std::string_view text, const Resolver& resolve);

  Node unary(Op op, Node a);
  Node binary(Op op, Node a, Node b);

  // Exact symbolic derivative d f / d (variable `slot`), simplified. abs, min and max are differentiated
  // piecewise (sign(x), and the derivative of the selected argument; at ties the first argument).
  Node derivative(Node f, int slot);

  bool depends_on(Node f, int slot) const;
  // True when f is built only from operations that are C-infinity on all of R^k (constants, variables,
  // +, -, *, negation, non-negative integer powers, sin, cos, atan, sinh, cosh, tanh, exp): then f is
  // locally Lipschitz everywhere. False for /, log, sqrt, tan, asin, acos, atan2, other powers, abs, min,
  // max (smooth on a domain only, or not smooth): nothing is concluded then.
  bool smooth_everywhere(Node f) const;
  bool is_constant(Node f) const;
  double constant_value(Node f) const;  // precondition: is_constant(f)
  std::string to_string(Node f) const;  // fully parenthesised, for messages and tests
  std::string to_string(Node f, const SlotNamer& slot_name) const;

  std::size_t size() const;

  struct Entry {
    Op op;
    Node a = -1, b = -1;
    double value = 0.0;   // kConst
    int slot = -1;        // kVar
    Node c = -1, d = -1;  // kSelectLe only (declared last so that {op, a, b} initialisation still works)
  };
  const Entry& entry(Node n) const;
  // Whether some node reachable from f (f included) satisfies `found`: one traversal for every such query.
  bool any_reachable(Node f, const std::function<bool(const Entry&)>& found) const;

 private:
  // Returns the shared node equal to `e`, adding it if new. All nodes are created here.
  Node intern(const Entry& e);
  // (a <= b) ? c : d, simplified; only the derivative of min/max creates it.
  Node select_le(Node a, Node b, Node c, Node d);
  void check_node(Node n) const;

  std::vector<Entry> nodes_;
  struct Impl;  // hash index for hash-consing, defined in expression.cc
  std::shared_ptr<Impl> index_;
};

// A straight-line program computing several outputs of a Graph at once. Evaluation allocates nothing:
// the caller owns the scratch buffer (scratch_size() doubles), so one Tape can serve many threads.
class Tape {
 public:
  Tape() = default;
  // Compiles `outputs` (nodes of `graph`), keeping only the nodes they reach, in topological order.
  // `num_slots` is the number of inputs. A kVar slot in [num_slots, num_slots + num_params) is parameter
  // slot - num_slots: a named constant of the tape, set by bind(), not an input of eval(). Every node
  // that depends on parameters and constants alone is computed by bind(), with the operations constant
  // folding uses (Graph's fold), so that a bound tape computes what the tape of the expressions with the
  // parameters folded in computes; eval() does no more work than for that tape (compile() also makes the
  // rewrites the graph makes with a constant, -(c*x) = (-c)*x and c*(-y) = (-c)*y, for a bound c).
  static Tape compile(const Graph& graph, const std::vector<Node>& outputs, int num_slots, int num_params = 0);

  // Sets the parameters (num_params() values) and recomputes the nodes that depend on them alone. Until
  // the first bind, they are NaN. Returns false when one of those nodes is 0: the graph folds 0 + x,
  // 0 * x, ... for a constant 0, so there the folded tape may differ in the sign of a zero (or give 0
  // where 0 * inf is NaN); callers that promise the folded tape's bits compile such values in full.
  [[nodiscard]] bool bind(const double* params);
  int num_params() const { return num_params_; }

  // outputs[i] = value of the i-th output node for inputs `slots`.
  void eval(const double* slots, double* outputs, double* scratch) const;

  // eval() in its parts, for a caller that runs one tape at every step from a scratch of its own (the
  // scene's step, scene_model.h): it writes the constants once, then at each evaluation the inputs
  // straight into their registers, runs the instructions and reads the outputs from their registers,
  // sparing the copies eval() makes through `slots` and `outputs`. Same instructions, same bits.
  void load_constants(double* scratch) const;   // the constants run() reads (again after a bind())
  std::int32_t input_register(int slot) const;  // where input `slot` goes, -1 if the tape reads none
  std::int32_t output_register(std::size_t j) const { return output_regs_[j]; }
  void run(double* scratch) const {  // the instructions alone
    if (native_run_ != nullptr) return native_run_(scratch);
    run_interpreted(scratch);
  }

  // A tape wired to its caller's arrays: run_wired() reads input slot k from sources[p.array][p.index] for
  // p = inputs[k] and writes output j to sinks[p.array][p.index] for every p in outputs[j], with no copy
  // through `slots` or an output array; its native code reads the inputs where they are, keeps the values
  // it computes in registers between calls (and still stores every one in the scratch) and writes each
  // output where it goes as soon as it is computed. The scratch must hold the constants (load_constants()),
  // and no sink may overlap a source (an input is read when first used, possibly after outputs are written).
  // The scene's step runs this way (scene_model.h): t, q, v in, the entries of M, C and g out.
  struct Place {
    std::int32_t array = -1;  // an index into sources or sinks; -1 for an input slot the caller does not give
    std::int32_t index = 0;   // the element of that array
  };
  struct Wiring {
    std::vector<Place> inputs;                // by input slot: each slot the tape reads needs an array
    std::vector<std::vector<Place>> outputs;  // by output: every place it is written to
  };
  // Throws std::invalid_argument when the wiring leaves an input the tape reads without a place, or has
  // too few outputs.
  void wire(const Wiring& wiring);
  // Always inlined: a scene model runs its tapes from every step, and whether GCC inlined this two-line
  // trampoline there depended on how large the rest of the translation unit was (a larger Moreau-Jean
  // step made it a call again in the bouncing ball's loop: +8 instructions per step, callgrind).
  [[gnu::always_inline]] void run_wired(double* scratch, const double* const* sources, double* const* sinks) const {
    if (native_run_wired_ != nullptr) return native_run_wired_(scratch, sources, sinks);
    run_wired_interpreted(scratch, sources, sinks);
  }

  // run() executes the tape's native code where it has some, and interprets the instructions otherwise.
  // Native code (x86-64, compiled once by Tape::compile): each instruction one SSE2 operation on the
  // scratch registers (min and max too) or a call of the very function the interpreter calls (libm's sin,
  // pow, ...; the helpers of sign and select), so that it computes bit for bit what the interpreter
  // computes (native_tape.cc). None on other processors, for a tape of more than kMaxNativeInstructions
  // instructions, or where the system refuses executable memory: the interpreter serves then.
  static constexpr std::size_t kMaxNativeInstructions = std::size_t{1} << 16;
  bool native() const { return native_ != nullptr; }
  bool native_wired() const { return native_run_wired_ != nullptr; }  // run_wired() runs native code
  void run_interpreted(double* scratch) const;                        // the interpreter alone: the reference of the native code
  struct NativeCode;                                                  // defined where the code is made (private to the library)

  std::size_t scratch_size() const { return scratch_size_; }
  std::size_t num_outputs() const { return output_regs_.size(); }
  // Executed instructions; constants and inputs occupy registers but are copied in bulk, not executed.
  std::size_t num_instructions() const { return code_.size(); }

 private:
  struct Instr {
    Op op;
    std::int32_t a, b;  // register indices
    std::int32_t c, d;  // register indices, kSelectLe only
    double value;       // unused: constants are not instructions but registers filled from constants_
  };
  // Register layout: constants_ first, then the inputs named by input_slots_, then one register per
  // instruction (instruction i writes register first_instr_reg_ + i). Leaves are copied in bulk instead of
  // being dispatched one by one.
  std::vector<Instr> code_;
  std::vector<std::int32_t> output_regs_;
  std::size_t scratch_size_ = 0;
  std::vector<double> constants_;
  std::size_t num_read_constants_ = 0;  // constants_[0, this) are read by eval(); the rest only by bind()
  std::vector<std::int32_t> input_slots_;
  std::size_t first_instr_reg_ = 0;
  // Parameters: their registers (in the constants region) and, in order, the nodes that depend on
  // parameters and constants alone (each writes its own register of the constants region).
  struct BoundInstr {
    Op op;
    std::int32_t a, b, c, d;
    std::int32_t target;
  };
  int num_params_ = 0;
  std::vector<std::pair<std::int32_t, std::int32_t>> param_regs_;  // (register, parameter)
  std::vector<BoundInstr> bind_code_;
  std::vector<std::int32_t> pow_of_bound_;  // instructions x^p with p bound (x*x when p is 2)

  // The wiring as registers: input register <- sources[array][index], sinks[array][index] <- output register.
  struct Wire {
    std::int32_t reg, array, index;
  };
  // The native code of code_ (native_tape.cc), shared by the tape's copies: it reads its constants from
  // the scratch, so a bind() leaves it valid (x^p with p bound calls a helper that squares when p is 2).
  // Without wires: the code of run(scratch). With them: of run_wired (inputs from the sources, outputs to
  // the sinks).
  static std::shared_ptr<const NativeCode> compile_native(const Tape& tape, const std::vector<Wire>* inputs,
                                                          const std::vector<Wire>* outputs);
  std::vector<Wire> wired_inputs_, wired_outputs_;
  void run_wired_interpreted(double* scratch, const double* const* sources, double* const* sinks) const;
  std::shared_ptr<const NativeCode> native_, wired_native_;
  void (*native_run_)(double* scratch) = nullptr;                                                            // native_'s entry point
  void (*native_run_wired_)(double* scratch, const double* const* sources, double* const* sinks) = nullptr;  // wired_native_'s
};

}  // namespace moreau::expr

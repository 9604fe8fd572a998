// Native code for a Tape: one pass over its instructions emits x86-64 machine code (with Xbyak, an x86
// assembler in a header) that does what Tape::run_interpreted does, without the interpreter's dispatch:
// per instruction, the interpreter loads the instruction, jumps through its switch and loads its operand
// registers; the native code is the operation alone, its register indices built into the addresses.
//
// Bit for bit the interpreter's values, by construction: +, -, *, / and sqrt are the same IEEE operations
// (SSE2 addsd, subsd, mulsd, divsd, sqrtsd: correctly rounded, as the interpreter's are); -x and |x| flip
// or clear the sign bit as the compiler's code for -x and std::fabs does; min and max are minsd and maxsd
// with their operands in the order that makes them the interpreter's comparisons, ties and NaNs included;
// every other operation is a call of the very function the interpreter calls (libm's sin, cos, sincos,
// pow, ...; the helpers of expression_arithmetic.h for sign and select). tests/expr/expression_test.cc checks
// it on every operation at special values and on random expressions, and the expression fuzzer on any
// expression it finds.
//
// The code is written into memory that is writable and not executable, then made executable and not
// writable (W^X) before it is ever run. Its only inputs are the tape's own instructions (operations of a
// fixed set, register indices that Tape::compile made, all inside the scratch) and the addresses of those
// functions: nothing of a scene's text reaches it but through them.
#include "native_tape.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <unordered_map>
#include <utility>
#include <vector>

#if defined(__x86_64__) && defined(__linux__) && __has_include(<xbyak/xbyak.h>)
#define MOREAU_NATIVE_TAPES 1
#define XBYAK_NO_OP_NAMES
#include <xbyak/xbyak.h>
#endif

#include "expression_arithmetic.h"

namespace moreau::expr {

#if MOREAU_NATIVE_TAPES

namespace {

// The calls the native code makes (System V ABI: doubles in and out through xmm0-xmm3).
double call_sign(double x) { return arithmetic::sign_of(x); }
double call_select_le(double a, double b, double c, double d) { return arithmetic::select_le_of(a, b, c, d); }
// x^p with p a parameter: Tape::bind turns the interpreter's instruction into x*x when p is 2 and back to
// pow otherwise; the native code, compiled once, decides at the call from the p in the scratch.
double call_pow_of_bound(double x, double p) { return p == 2.0 ? x * x : std::pow(x, p); }

// Thrown when code compiled as call-free would call (see `call` in compile_native).
struct CallInCallFreeCode {};

// The operations the native code does with SSE2 instructions of its own; every other one is a call.
bool emitted_inline(Op op) {
  switch (op) {
    case Op::kAdd:
    case Op::kSub:
    case Op::kMul:
    case Op::kDiv:
    case Op::kMin:
    case Op::kMax:
    case Op::kSquare:
    case Op::kSqrt:
    case Op::kNeg:
    case Op::kAbs: return true;
    default: return false;
  }
}

using Unary = double (*)(double);
using Binary = double (*)(double, double);

// The libm function an operation calls, as the interpreter calls it (std::sin is ::sin, ...).
Unary libm_unary(Op op) {
  switch (op) {
    case Op::kSin: return static_cast<Unary>(&std::sin);
    case Op::kCos: return static_cast<Unary>(&std::cos);
    case Op::kTan: return static_cast<Unary>(&std::tan);
    case Op::kAsin: return static_cast<Unary>(&std::asin);
    case Op::kAcos: return static_cast<Unary>(&std::acos);
    case Op::kAtan: return static_cast<Unary>(&std::atan);
    case Op::kSinh: return static_cast<Unary>(&std::sinh);
    case Op::kCosh: return static_cast<Unary>(&std::cosh);
    case Op::kTanh: return static_cast<Unary>(&std::tanh);
    case Op::kExp: return static_cast<Unary>(&std::exp);
    case Op::kLog: return static_cast<Unary>(&std::log);
    case Op::kSign: return &call_sign;
    default: return nullptr;
  }
}

struct XbyakCode final : Tape::NativeCode {
  explicit XbyakCode(std::size_t max_bytes) : gen(max_bytes, Xbyak::DontSetProtectRWE) {}
  Xbyak::CodeGenerator gen;  // owns the code's memory
};

// The most bytes one instruction's code takes (a call with four operands read from a caller's arrays:
// 4 x 16, a 10-byte address, the call, a copy, a store), and one wire's (a pointer load and a store).
constexpr std::size_t kMaxBytesPerInstruction = 160;
constexpr std::size_t kMaxBytesPerWire = 32;

// Writes the code of one tape. Registers: the scratch, the sources and the sinks stay where the caller
// passed them (rdi, rsi, rdx) in code that calls nothing, and move to rbx, r12 and r13 (callee-saved: they
// survive the calls) in code that calls; rax a temporary; xmm0-xmm3 the arguments of calls and xmm1 a sign mask;
// xmm4-xmm15 hold the values last computed or read, so that an instruction takes its operands from a
// register rather than reloading what was just stored (a call clobbers them all).
class Emitter {
 public:
  Emitter(Xbyak::CodeGenerator& g, std::size_t scratch_size, bool calls)
      : g_(g),
        scratch_(calls ? g.rbx : g.rdi),
        sources_(calls ? g.r12 : g.rsi),
        sinks_(calls ? g.r13 : g.rdx),
        cached_in_(scratch_size, -1),
        input_at_(scratch_size, {-1, 0}) {
    for (int& h : holder_) h = -1;
  }

  // Input register r is read from sources[array][index] rather than from the scratch.
  void read_from(std::int32_t r, std::int32_t array, std::int32_t index) { input_at_[static_cast<std::size_t>(r)] = {array, index}; }
  // Register r, once computed, is also written to sinks[array][index].
  void write_to(std::int32_t r, std::int32_t array, std::int32_t index) { sinks_of_[r].push_back({array, index}); }

  Xbyak::Address at(std::int64_t r) { return g_.qword[scratch_ + static_cast<std::int32_t>(8 * r)]; }

  // xmm `x` <- register r: from the register that holds it, the caller's array, or the scratch.
  void load(const Xbyak::Xmm& x, std::int32_t r) {
    const int k = cached_in_[static_cast<std::size_t>(r)];
    if (k >= 0) {
      if (k != x.getIdx()) g_.movapd(x, Xbyak::Xmm(k));
    } else if (const auto [array, index] = input_at_[static_cast<std::size_t>(r)]; array >= 0) {
      g_.mov(g_.rax, g_.qword[sources_ + 8 * array]);
      g_.movsd(x, g_.qword[g_.rax + 8 * index]);
    } else {
      g_.movsd(x, at(r));
    }
  }
  // A register of the pool holding r's value (loading it when none does), other than those of `keep`.
  Xbyak::Xmm operand(std::int32_t r, std::int32_t keep = -1) {
    if (const int k = cached_in_[static_cast<std::size_t>(r)]; k >= 0) return Xbyak::Xmm(k);
    const Xbyak::Xmm x = fresh(keep, -1);
    load(x, r);
    hold(x.getIdx(), r);
    return x;
  }
  // A register of the pool for a new value, other than those holding `keep1` and `keep2`.
  Xbyak::Xmm fresh(std::int32_t keep1, std::int32_t keep2) {
    const int avoid1 = keep1 >= 0 ? cached_in_[static_cast<std::size_t>(keep1)] : -1;
    const int avoid2 = keep2 >= 0 ? cached_in_[static_cast<std::size_t>(keep2)] : -1;
    int k;
    do {
      k = kFirstPool + next_;
      next_ = (next_ + 1) % kPoolSize;
    } while (k == avoid1 || k == avoid2);
    if (holder_[k] >= 0) cached_in_[static_cast<std::size_t>(holder_[k])] = -1;
    holder_[k] = -1;
    return Xbyak::Xmm(k);
  }
  void hold(int k, std::int32_t r) {
    if (holder_[k] >= 0) cached_in_[static_cast<std::size_t>(holder_[k])] = -1;
    holder_[k] = r;
    cached_in_[static_cast<std::size_t>(r)] = k;
  }
  // After a call: every xmm register may have changed.
  void forget_all() {
    for (int k = kFirstPool; k < kFirstPool + kPoolSize; ++k) {
      if (holder_[k] >= 0) cached_in_[static_cast<std::size_t>(holder_[k])] = -1;
      holder_[k] = -1;
    }
  }
  // r's value is in x (a register of the pool): remember it, store it in the scratch, write it to its sinks.
  void computed(std::int32_t r, const Xbyak::Xmm& x, bool store = true) {
    hold(x.getIdx(), r);
    if (store) g_.movsd(at(r), x);
    write_sinks(r, x);
  }
  void write_sinks(std::int32_t r, const Xbyak::Xmm& x) {
    const auto it = sinks_of_.find(r);
    if (it == sinks_of_.end()) return;
    for (const auto& [array, index] : it->second) {
      g_.mov(g_.rax, g_.qword[sinks_ + 8 * array]);
      g_.movsd(g_.qword[g_.rax + 8 * index], x);
    }
  }
  const std::unordered_map<std::int32_t, std::vector<std::pair<std::int32_t, std::int32_t>>>& sinks() const { return sinks_of_; }

 private:
  static constexpr int kFirstPool = 4, kPoolSize = 12;
  Xbyak::CodeGenerator& g_;
  const Xbyak::Reg64 scratch_, sources_, sinks_;
  std::vector<int> cached_in_;  // scratch register -> the xmm holding its value, or -1
  int holder_[16];              // xmm -> the scratch register whose value it holds, or -1
  int next_ = 0;
  std::vector<std::pair<std::int32_t, std::int32_t>> input_at_;  // scratch register -> (source array, index), or -1
  std::unordered_map<std::int32_t, std::vector<std::pair<std::int32_t, std::int32_t>>> sinks_of_;
};

}  // namespace

std::shared_ptr<const Tape::NativeCode> Tape::compile_native(const Tape& tape, const std::vector<Wire>* inputs,
                                                             const std::vector<Wire>* outputs) {
  using namespace Xbyak::util;
  const std::vector<Instr>& code = tape.code_;
  const std::size_t first_instr_reg = tape.first_instr_reg_;
  // Bounded code size. A tape without instructions has nothing to gain unwired (its run does nothing), but
  // wired it still copies inputs and constants to their sinks, and the interpreter's loops over the wires
  // cost more than the copies (a contact whose gap is a coordinate: the bouncing ball's constraint tape).
  const bool wired = inputs != nullptr || outputs != nullptr;
  if ((code.empty() && !wired) || code.size() > kMaxNativeInstructions) return nullptr;
  try {
    const std::size_t wires = (inputs ? inputs->size() : 0) + (outputs ? outputs->size() : 0);
    auto native = std::make_shared<XbyakCode>(256 + kMaxBytesPerInstruction * code.size() + kMaxBytesPerWire * wires);
    Xbyak::CodeGenerator& g = native->gen;
    // Whether the code calls (libm, the helpers): only then need the pointers survive calls.
    const bool calls = std::any_of(code.begin(), code.end(), [](const Instr& in) { return !emitted_inline(in.op); });
    Emitter e(g, tape.scratch_size_, calls);
    if (inputs)
      for (const Wire& w : *inputs) e.read_from(w.reg, w.array, w.index);
    if (outputs)
      for (const Wire& w : *outputs) e.write_to(w.reg, w.array, w.index);
    std::vector<char> is_pow_of_bound(code.size(), 0);
    for (std::int32_t i : tape.pow_of_bound_) is_pow_of_bound[static_cast<std::size_t>(i)] = 1;

    auto call = [&](const void* function) {
      // Call-free code keeps the caller's pointers in rdi, rsi and rdx, which a call clobbers: an operation
      // that calls but that emitted_inline() lists as inline would corrupt them. Refuse, and the
      // interpreter serves (ExprTest.NativeCodeComputesEveryOperation requires native code for every
      // operation, so such a mistake fails there).
      if (!calls) throw CallInCallFreeCode{};
      g.mov(rax, reinterpret_cast<std::uint64_t>(function));
      g.call(rax);
      e.forget_all();
    };
    if (calls) {  // three pushes also align the stack to the 16 bytes a call needs
      g.push(rbx);
      g.push(r12);
      g.push(r13);
      g.mov(rbx, rdi);
      g.mov(r12, rsi);
      g.mov(r13, rdx);
    }
    for (std::size_t i = 0; i < code.size(); ++i) {
      const Instr& in = code[i];
      const auto target = static_cast<std::int32_t>(first_instr_reg + i);
      switch (in.op) {
        case Op::kAdd:
        case Op::kSub:
        case Op::kMul:
        case Op::kDiv:
        case Op::kMin:    // min_of(a, b) = b < a ? b : a: minsd with b first (its second operand wins ties and NaNs)
        case Op::kMax: {  // max_of(a, b) = a < b ? b : a = (b > a ? b : a): maxsd with b first
          const Xbyak::Xmm a = e.operand(in.a), b = e.operand(in.b, in.a), d = e.fresh(in.a, in.b);
          if (in.op == Op::kMin || in.op == Op::kMax) {
            g.movapd(d, b);
            in.op == Op::kMin ? g.minsd(d, a) : g.maxsd(d, a);
          } else {
            g.movapd(d, a);
            switch (in.op) {
              case Op::kAdd: g.addsd(d, b); break;
              case Op::kSub: g.subsd(d, b); break;
              case Op::kMul: g.mulsd(d, b); break;
              default: g.divsd(d, b); break;
            }
          }
          e.computed(target, d);
          continue;
        }
        case Op::kSquare:
        case Op::kSqrt:
        case Op::kNeg:
        case Op::kAbs: {
          const Xbyak::Xmm a = e.operand(in.a), d = e.fresh(in.a, -1);
          if (in.op == Op::kSqrt) {
            g.sqrtsd(d, a);
          } else {
            g.movapd(d, a);
            if (in.op == Op::kSquare) {
              g.mulsd(d, d);
            } else {
              g.mov(rax, in.op == Op::kNeg ? std::uint64_t{0x8000'0000'0000'0000} : std::uint64_t{0x7fff'ffff'ffff'ffff});
              g.movq(xmm1, rax);
              in.op == Op::kNeg ? g.xorpd(d, xmm1) : g.andpd(d, xmm1);
            }
          }
          e.computed(target, d);
          continue;
        }
        case Op::kSinCos: {
          // sin into this instruction's register, cos into the next one's; the next instruction is not run.
          e.load(xmm0, in.a);
          g.lea(rdi, e.at(target));
          g.lea(rsi, e.at(target + 1));
          call(reinterpret_cast<const void*>(static_cast<void (*)(double, double*, double*)>(&::sincos)));
          for (const std::int32_t r : {target, target + 1}) {
            const Xbyak::Xmm d = e.fresh(target, -1);
            g.movsd(d, e.at(r));
            e.computed(r, d, /*store=*/false);
          }
          ++i;
          continue;
        }
        case Op::kPow:
        case Op::kAtan2:
          e.load(xmm0, in.a);
          e.load(xmm1, in.b);
          call(in.op == Op::kAtan2       ? reinterpret_cast<const void*>(static_cast<Binary>(&std::atan2))
               : is_pow_of_bound[i] != 0 ? reinterpret_cast<const void*>(&call_pow_of_bound)
                                         : reinterpret_cast<const void*>(static_cast<Binary>(&std::pow)));
          break;
        case Op::kSelectLe:
          e.load(xmm0, in.a);
          e.load(xmm1, in.b);
          e.load(xmm2, in.c);
          e.load(xmm3, in.d);
          call(reinterpret_cast<const void*>(&call_select_le));
          break;
        default: {
          const Unary f = libm_unary(in.op);
          if (f == nullptr) return nullptr;  // not an instruction (a leaf): leave the tape to the interpreter
          e.load(xmm0, in.a);
          call(reinterpret_cast<const void*>(f));
          break;
        }
      }
      // A call's result, in xmm0.
      const Xbyak::Xmm d = e.fresh(-1, -1);
      g.movapd(d, xmm0);
      e.computed(target, d);
    }
    // Outputs that no instruction computes: constants (in the scratch) and inputs.
    for (const auto& [r, places] : e.sinks()) {
      if (static_cast<std::size_t>(r) >= first_instr_reg) continue;
      e.load(xmm0, r);
      e.write_sinks(r, xmm0);
    }
    if (calls) {
      g.pop(r13);
      g.pop(r12);
      g.pop(rbx);
    }
    g.ret();
    g.setProtectModeRE();  // W^X: executable from here on, never writable again
    if (wired)
      native->run_wired = g.getCode<void (*)(double*, const double* const*, double* const*)>();
    else
      native->run = g.getCode<void (*)(double*)>();
    return native;
  } catch (const CallInCallFreeCode&) {
    return nullptr;
  } catch (const Xbyak::Error&) {
    return nullptr;  // no executable memory (a hardened system) or no room: the interpreter serves
  } catch (const std::bad_alloc&) {
    return nullptr;
  }
}

#else

// No native code generator for this processor or system: every tape is interpreted.
std::shared_ptr<const Tape::NativeCode> Tape::compile_native(const Tape&, const std::vector<Wire>*, const std::vector<Wire>*) {
  return nullptr;
}

#endif

}  // namespace moreau::expr

// The native code of a Tape (Tape::compile_native, native_tape.cc): machine code that does what
// Tape::run_interpreted does, bit for bit. Private to the expression library.
#pragma once

#include "moreau/expr/expression.h"

namespace moreau::expr {

struct Tape::NativeCode {
  virtual ~NativeCode() = default;
  // The entry point (run, or run_wired for a wired tape's code); the code lives as long as this object.
  void (*run)(double* scratch) = nullptr;
  void (*run_wired)(double* scratch, const double* const* sources, double* const* sinks) = nullptr;
};

}  // namespace moreau::expr

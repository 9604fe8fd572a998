// A SparseVectorFunction (core/include/moreau/core/sparse_vector_function.h) compiled from a scene's
// expressions: f(q) and the nonzeros of its Jacobian in a fixed pattern, as tapes of at most
// kOutputsPerTape components. Used for the nonlinear gaps of the large-contact path (h(q) and the exact
// symbolic derivatives of each gap in the coordinates it reads) and for grad V of the large ABL path (its
// components, no Jacobian). Small tapes run as native code; one tape for ten thousand components would
// exceed Tape::kMaxNativeInstructions and be interpreted. Each tape reads only the coordinates its
// components read.
#pragma once

#include <utility>
#include <vector>

#include "moreau/core/large_contact_system.h"
#include "moreau/expr/expression.h"

namespace moreau::scene::detail {

class SparseVectorTapes final : public SparseVectorFunction {
 public:
  static constexpr int kOutputsPerTape = 256;

  // values[i] = f_i; partials[i] = (coordinate j, d f_i / d q_j) for the Jacobian's pattern in row i,
  // j increasing (empty rows: no Jacobian). The graph's variable slot of q_j is 1 + j (the scene's
  // slots: t, q, v); `num_slots` is their number. The expressions read q alone.
  SparseVectorTapes(const expr::Graph& graph, const std::vector<expr::Node>& values,
                    const std::vector<std::vector<std::pair<int, expr::Node>>>& partials, int num_slots);

  std::vector<double> make_scratch() const override;
  void evaluate(const double* q, double* value, double* jacobian, double* scratch) const override;

 private:
  struct Chunk {
    expr::Tape tape;  // outputs: its components, then their partials; wired to q, value + first_output, jacobian + first_entry
    int first_output = 0;
    int first_entry = 0;
    std::size_t scratch_offset = 0;
  };
  std::vector<Chunk> chunks_;
  std::size_t scratch_size_ = 0;
};

}  // namespace moreau::scene::detail

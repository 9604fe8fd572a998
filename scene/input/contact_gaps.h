// The nonlinear gaps of a scene on the large-contact path (large_contact_system.h): h(q) and the nonzeros
// of grad h(q)^T, compiled from the scene's expressions (their exact symbolic derivatives, in the
// coordinates each gap reads) into tapes of at most kGapsPerTape gaps. Small tapes run as native code;
// one tape for ten thousand gaps would exceed Tape::kMaxNativeInstructions and be interpreted.
#pragma once

#include <utility>
#include <vector>

#include "moreau/core/large_contact_system.h"
#include "moreau/expr/expression.h"

namespace moreau::scene::detail {

class ContactGapTapes final : public ContactGapFunction {
 public:
  static constexpr int kGapsPerTape = 256;

  // gaps[i] = h_i; partials[i] = (coordinate j, d h_i / d q_j) for every coordinate h_i reads, j
  // increasing. The graph's variable slot of q_j is 1 + j (the scene's slots: t, q, v); `num_slots` is
  // their number.
  ContactGapTapes(const expr::Graph& graph, const std::vector<expr::Node>& gaps,
                  const std::vector<std::vector<std::pair<int, expr::Node>>>& partials, int num_slots);

  std::vector<double> make_scratch() const override;
  void evaluate(const double* q, double* gap, double* gradient, double* scratch) const override;

 private:
  struct Chunk {
    expr::Tape tape;  // outputs: its gaps, then their partials; wired to q, gap + first_gap, gradient + first_value
    int first_gap = 0;
    int first_value = 0;
    std::size_t scratch_offset = 0;
  };
  std::vector<Chunk> chunks_;
  std::size_t scratch_size_ = 0;
};

}  // namespace moreau::scene::detail

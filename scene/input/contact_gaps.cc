#include "contact_gaps.h"

#include <algorithm>

namespace moreau::scene::detail {

ContactGapTapes::ContactGapTapes(const expr::Graph& graph, const std::vector<expr::Node>& gaps,
                                 const std::vector<std::vector<std::pair<int, expr::Node>>>& partials, int num_slots) {
  const int m = static_cast<int>(gaps.size());
  int value = 0;
  for (int first = 0; first < m; first += kGapsPerTape) {
    const int last = std::min(m, first + kGapsPerTape);
    std::vector<expr::Node> outputs(gaps.begin() + first, gaps.begin() + last);
    expr::Tape::Wiring w;
    w.inputs.resize(static_cast<std::size_t>(num_slots));
    for (int i = first; i < last; ++i) {
      w.outputs.push_back({{0, i - first}});
      for (const auto& [j, node] : partials[static_cast<std::size_t>(i)]) {
        w.inputs[static_cast<std::size_t>(1 + j)] = {0, j};
        outputs.push_back(node);
      }
    }
    Chunk c;
    c.first_gap = first;
    c.first_value = value;
    for (int i = first, k = 0; i < last; ++i)
      for (std::size_t p = 0; p < partials[static_cast<std::size_t>(i)].size(); ++p) w.outputs.push_back({{1, k++}});
    for (int i = first; i < last; ++i) value += static_cast<int>(partials[static_cast<std::size_t>(i)].size());
    c.tape = expr::Tape::compile(graph, outputs, num_slots);
    c.tape.wire(w);
    c.scratch_offset = scratch_size_;
    scratch_size_ += c.tape.scratch_size();
    chunks_.push_back(std::move(c));
  }
}

std::vector<double> ContactGapTapes::make_scratch() const {
  std::vector<double> scratch(scratch_size_, 0.0);
  for (const Chunk& c : chunks_) c.tape.load_constants(scratch.data() + c.scratch_offset);
  return scratch;
}

void ContactGapTapes::evaluate(const double* q, double* gap, double* gradient, double* scratch) const {
  for (const Chunk& c : chunks_) {
    const double* sources[] = {q};
    double* sinks[] = {gap + c.first_gap, gradient + c.first_value};
    c.tape.run_wired(scratch + c.scratch_offset, sources, sinks);
  }
}

}  // namespace moreau::scene::detail

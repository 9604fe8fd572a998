#include "sparse_vector_tapes.h"

#include <algorithm>

namespace moreau::scene::detail {

namespace {

// The coordinate slots 1 .. n that the nodes read (num_slots = 1 + 2 n: t, q, v; the functions read q
// only), increasing: one traversal of their nodes.
std::vector<int> slots_read(const expr::Graph& graph, const std::vector<expr::Node>& nodes, int num_slots) {
  std::vector<char> seen(graph.size(), 0), slot_read(static_cast<std::size_t>(num_slots), 0);
  std::vector<expr::Node> stack;
  for (expr::Node n : nodes)
    if (n >= 0 && !seen[static_cast<std::size_t>(n)]) {
      seen[static_cast<std::size_t>(n)] = 1;
      stack.push_back(n);
    }
  while (!stack.empty()) {
    const expr::Graph::Entry& e = graph.entry(stack.back());
    stack.pop_back();
    if (e.op == expr::Op::kVar && e.slot >= 1 && e.slot <= (num_slots - 1) / 2) slot_read[static_cast<std::size_t>(e.slot)] = 1;
    for (expr::Node child : {e.a, e.b, e.c, e.d})
      if (child >= 0 && !seen[static_cast<std::size_t>(child)]) {
        seen[static_cast<std::size_t>(child)] = 1;
        stack.push_back(child);
      }
  }
  std::vector<int> slots;
  for (int s = 1; s < num_slots; ++s)
    if (slot_read[static_cast<std::size_t>(s)]) slots.push_back(s);
  return slots;
}

}  // namespace

SparseVectorTapes::SparseVectorTapes(const expr::Graph& graph, const std::vector<expr::Node>& values,
                                     const std::vector<std::vector<std::pair<int, expr::Node>>>& partials, int num_slots) {
  const int m = static_cast<int>(values.size());
  int entry = 0;
  for (int first = 0; first < m; first += kOutputsPerTape) {
    const int last = std::min(m, first + kOutputsPerTape);
    std::vector<expr::Node> outputs(values.begin() + first, values.begin() + last);
    expr::Tape::Wiring w;
    w.inputs.resize(static_cast<std::size_t>(num_slots));
    for (int i = first; i < last; ++i) {
      w.outputs.push_back({{0, i - first}});
      for (const auto& [j, node] : partials[static_cast<std::size_t>(i)]) outputs.push_back(node);
    }
    // The tape reads the coordinates its outputs read, and only those: q_j from sources[0][j].
    for (int slot : slots_read(graph, outputs, num_slots)) w.inputs[static_cast<std::size_t>(slot)] = {0, slot - 1};
    Chunk c;
    c.first_output = first;
    c.first_entry = entry;
    for (int i = first, k = 0; i < last; ++i)
      for (std::size_t p = 0; p < partials[static_cast<std::size_t>(i)].size(); ++p) w.outputs.push_back({{1, k++}});
    for (int i = first; i < last; ++i) entry += static_cast<int>(partials[static_cast<std::size_t>(i)].size());
    c.tape = expr::Tape::compile(graph, outputs, num_slots);
    c.tape.wire(w);
    c.scratch_offset = scratch_size_;
    scratch_size_ += c.tape.scratch_size();
    chunks_.push_back(std::move(c));
  }
}

std::vector<double> SparseVectorTapes::make_scratch() const {
  std::vector<double> scratch(scratch_size_, 0.0);
  for (const Chunk& c : chunks_) c.tape.load_constants(scratch.data() + c.scratch_offset);
  return scratch;
}

void SparseVectorTapes::evaluate(const double* q, double* value, double* jacobian, double* scratch) const {
  for (const Chunk& c : chunks_) {
    const double* sources[] = {q};
    double* sinks[] = {value + c.first_output, jacobian ? jacobian + c.first_entry : nullptr};
    c.tape.run_wired(scratch + c.scratch_offset, sources, sinks);
  }
}

}  // namespace moreau::scene::detail

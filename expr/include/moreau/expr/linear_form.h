// An expression as an affine form c + sum_j a_j x_j when it is one: what the large-contact path of a
// scene needs of its gaps and potential (a gradient that is the same at every q), read off the graph in
// time linear in the expression's size, without differentiating once per variable (n derivatives of a
// potential with n terms would cost n^2).
#pragma once

#include <optional>
#include <utility>
#include <vector>

#include "moreau/expr/expression.h"

namespace moreau::expr {

struct AffineForm {
  double constant = 0.0;                             // the value at x = 0
  std::vector<std::pair<int, double>> coefficients;  // (slot, a_slot), slots increasing, a_slot != 0
};

// f as an affine form in the variable slots, or nullopt when f is not affine by its structure: built from
// constants and variables by +, -, unary -, a product with a constant factor and a division by a
// constant (the graph folds constant subexpressions, so these are the only operations an affine
// expression needs). A structurally nonlinear expression that happens to be affine (x*x - x*x folds, but
// sin(x)^2 + cos(x)^2 does not) is reported as not affine: the answer errs on the side of "not shown".
std::optional<AffineForm> affine_form(const Graph& graph, Node f);

}  // namespace moreau::expr

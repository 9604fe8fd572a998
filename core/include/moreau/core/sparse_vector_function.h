// A vector function of the coordinates, f: R^n -> R^m, each of whose components reads a few coordinates,
// always the same ones: the gaps of a contact system at scale (large_contact_system.h) and the potential's
// gradient of a system at scale (large_abl_system.h). It returns f(q) and, where the caller asks for them,
// the nonzeros of its Jacobian in a fixed pattern. No I/O: the scene compiles its expressions into one
// (scene/input/sparse_vector_tapes.h); tests write theirs by hand.
#pragma once

#include <vector>

namespace moreau {

// Const and reentrant (one function serves every run of a scene, on any thread): the state of an
// evaluation lives in the caller's scratch.
class SparseVectorFunction {
 public:
  virtual ~SparseVectorFunction() = default;
  // A scratch for evaluate(), sized and initialised (the constants the evaluation reads).
  virtual std::vector<double> make_scratch() const = 0;
  // value[i] = f_i(q) for every component i; jacobian[k] = the k-th stored entry of the Jacobian in its
  // fixed pattern (row-major: component by component, coordinates increasing). A function whose pattern
  // is empty (the gradient of a potential, whose Jacobian the scheme does not use) never writes jacobian.
  virtual void evaluate(const double* q, double* value, double* jacobian, double* scratch) const = 0;
};

}  // namespace moreau

// A compiled Lagrangian scene as a model of the ABL integrator (see abl_integrator.h for the model
// requirements) and of the Moreau-Jean integrator (moreau_jean_integrator.h: constraints, restitution,
// potential). evaluate() runs one tape for every non-constant entry of M, C and g = grad V + F, which
// writes the values over the constant parts; constraints() runs one tape for the gaps h_i(q) and their
// exact gradients, potential() one for V(q), evaluate_with_potential() one for the terms and V together.
// Each tape is wired to where its caller holds q and wants the results (Tape::run_wired): no copy, no
// allocation, no virtual call.
#pragma once

#include <algorithm>
#include <cassert>
#include <memory>
#include <numeric>
#include <type_traits>
#include <vector>

#include "moreau/scene/scene.h"

namespace moreau::scene {

// The numbers of degrees of freedom compiled as fixed-size Eigen code: 1 to 4 (hand-written and small
// systems) and 6 and 7 (robot arms from URDF: fixed size halves their step, docs/robots.md); other
// sizes run on dynamic-size code. Each size costs compile time in three translation units, which is why
// 5 and 8+ are not listed. Every path that runs a Lagrangian scene (run, study, stress, server)
// dispatches through dispatch_dof, so they all have the same sizes.
inline constexpr int kFixedDofSizes[] = {1, 2, 3, 4, 6, 7};

inline constexpr bool is_fixed_dof(int n) {
  for (int size : kFixedDofSizes)
    if (size == n) return true;
  return false;
}

// Calls f(std::integral_constant<int, N>{}) with N = n for n in kFixedDofSizes, else with
// N = Eigen::Dynamic, and returns what f returns.
template <class F>
decltype(auto) dispatch_dof(int n, F&& f) {
  switch (n) {
    case 1: return f(std::integral_constant<int, 1>{});
    case 2: return f(std::integral_constant<int, 2>{});
    case 3: return f(std::integral_constant<int, 3>{});
    case 4: return f(std::integral_constant<int, 4>{});
    case 6: return f(std::integral_constant<int, 6>{});
    case 7: return f(std::integral_constant<int, 7>{});
    default: return f(std::integral_constant<int, Eigen::Dynamic>{});
  }
}
static_assert(sizeof(kFixedDofSizes) / sizeof(int) == 6, "dispatch_dof lists the fixed sizes one by one");

template <int N>
class SceneModel {
 public:
  static constexpr int kDof = N;

  explicit SceneModel(const LagrangianScene& scene) : c_(*scene.compiled), n_(scene.n), restitution_(scene.restitution) {
    phi_.weights = scene.controller.weights;
    phi_.gains = scene.controller.gains;
    phi_.norm_gain = scene.controller.norm_gain;
    step_.wire(c_.step_tape);
    mass_.wire(c_.mass_tape);
    potential_.wire(c_.potential_tape);
    step_potential_.wire(c_.step_potential_tape);
    constraints_.wire(c_.constraint_tape);
    constant_.resize(n_);
    load_constants(constant_);
    if (c_.robot) {
      robot_data_ = std::make_unique<RigidBodyData>(*c_.robot);
      gravity_.setZero(n_);
    }
  }

  int dof() const { return n_; }
  const Controller<N>& controller() const { return phi_; }
  bool constant_mass() const { return c_.constant_mass; }
  // M, C and g the same at every (t, q, v): nothing for the step tape to compute, no robot.
  bool constant_terms() const { return !c_.robot && !step_.active; }

  void evaluate(double t, const Vec<N>& q, const Vec<N>& v, LagrangianTerms<N>& out) {
    evaluate_terms(q, v, out, [&] {
      if (step_.active)  // none when all is constant
        step_.run(c_.step_tape, {&t, q.data(), v.data()}, {out.M.data(), out.C.data(), out.g.data()});
    });
  }

  int num_constraints() const { return c_.num_constraints; }
  double restitution(int i) const { return restitution_[i]; }
  bool has_potential() const { return c_.has_potential; }

  double potential(const Vec<N>& q) {
    double value = 0.0;
    if (potential_.active) potential_.run(c_.potential_tape, {q.data()}, {&value});  // CompiledLagrangian::potential_tape
    if (c_.robot) value += potential_energy(*c_.robot, *robot_data_, q.data());
    return value;
  }

  // evaluate() and potential() at one state, the same values: a scene's own potential from one tape with
  // the terms (CompiledLagrangian::step_potential_tape), which computes the sines, cosines and products
  // that V shares with M and grad V once.
  double evaluate_with_potential(double t, const Vec<N>& q, const Vec<N>& v, LagrangianTerms<N>& out) {
    if (!step_potential_.active) {  // no potential of the scene's own (none, or a robot's gravity alone)
      evaluate(t, q, v, out);
      return potential(q);
    }
    double value = 0.0;
    evaluate_terms(q, v, out, [&] {
      step_potential_.run(c_.step_potential_tape, {&t, q.data(), v.data()}, {out.M.data(), out.C.data(), out.g.data(), &value});
    });
    if (c_.robot) value += potential_energy(*c_.robot, *robot_data_, q.data());
    return value;
  }

  // gap(i) = h_i(q), H.row(i) = grad h_i(q)^T, written in place by the constraint tape, which is wired to
  // a gap vector of m entries and a column-major m x n matrix (CompiledLagrangian::constraint_tape).
  template <class Rows>
  void constraints(const Vec<N>& q, Eigen::VectorXd& gap, Rows& H) {
    static_assert(!Rows::IsRowMajor, "the constraint tape writes H column-major");
    if (!constraints_.active) return;
    assert(gap.size() == c_.num_constraints && H.rows() == c_.num_constraints && H.cols() == n_ && H.outerStride() == H.rows());
    constraints_.run(c_.constraint_tape, {q.data()}, {gap.data(), H.data()});
  }

  void mass(const Vec<N>& q, Mat<N>& M) {
    if (c_.robot) {
      mass_matrix(*c_.robot, *robot_data_, q.data(), M);
      return;
    }
    M = constant_.M;
    const double t = 0.0;  // M(q) reads no t, no v
    if (mass_.active) mass_.run(c_.mass_tape, {&t, q.data(), q.data()}, {M.data()});
  }

 private:
  // The terms at (q, v): their constant parts, the robot's M, C and gravity, and what run_tape writes
  // over them (the non-constant entries of M, C and g).
  template <class RunTape>
  void evaluate_terms(const Vec<N>& q, const Vec<N>& v, LagrangianTerms<N>& out, RunTape&& run_tape) {
    out.g = constant_.g;
    if (c_.robot) {
      // M, C and G = grad V of gravity from the robot (rigid_body.h); the step tape writes F (and a
      // potential's gradient) into g, and G is added after it.
      rigid_body_terms(*c_.robot, *robot_data_, q.data(), v.data(), out.M, out.C, gravity_);
    } else {
      out.M = constant_.M;
      out.C = constant_.C;
    }
    run_tape();
    if (c_.robot) out.g += gravity_;
  }

  void load_constants(LagrangianTerms<N>& t) const {
    const int nn = n_ * n_;
    for (int i = 0; i < nn; ++i) {
      t.M.data()[i] = c_.constant_terms[i];
      t.C.data()[i] = c_.constant_terms[nn + i];
    }
    for (int i = 0; i < n_; ++i) t.g(i) = c_.constant_terms[2 * nn + i];
  }

  const CompiledLagrangian& c_;
  int n_;
  Controller<N> phi_;
  LagrangianTerms<N> constant_;
  std::vector<double> restitution_;

  // A tape wired by the compiler to read its inputs from the caller's arrays and write its outputs into
  // them (Tape::run_wired; the arrays of each tape: CompiledLagrangian), run in a scratch of its own with
  // its constants loaded once.
  struct WiredTape {
    bool active = false;  // the tape has outputs
    std::vector<double> scratch;

    void wire(const expr::Tape& tape) {
      active = tape.num_outputs() > 0;
      scratch.assign(tape.scratch_size(), 0.0);
      tape.load_constants(scratch.data());
    }
    template <std::size_t kSources, std::size_t kSinks>
    void run(const expr::Tape& tape, const double* const (&sources)[kSources], double* const (&sinks)[kSinks]) {
      tape.run_wired(scratch.data(), sources, sinks);
    }
  };
  WiredTape step_, mass_, potential_, step_potential_, constraints_;
  std::unique_ptr<RigidBodyData> robot_data_;  // a URDF system's buffers
  Vec<N> gravity_;
};

// What the scheme (0.2) checks at its recorded states, apart from the step (which has only the sum
// g = grad V + F, and no V): Assumption 4.1 2)-3) from grad V and F (until it fails), and the total
// mechanical energy E = E_k + V(Q^k) with its balance E - E(t0) + D (MechanicalEnergyTrack). Every
// sample, and every other event, is passed on to `next`. run_scene attaches it; a study's error runs too.
class RecordedStateChecks final : public ForwardingObserver {
 public:
  RecordedStateChecks(const LagrangianScene& scene, RunObserver* next);
  // Assumption 4.1 at every kStride-th recorded state: one evaluation costs about as much as a step of
  // the relay, and states kStride steps apart are close; a failure found at any of them is a failure of
  // the assumption. E at every kEnergyStride-th: a potential costs a sine or a cosine on a 100 ns step, and
  // the balance's exact parts (D at every step, E at both ends) do not depend on it.
  static constexpr std::int64_t kStride = 16;
  static constexpr std::int64_t kEnergyStride = 64;
  void on_sample(const Sample& s) override;
  // With nothing to pass samples on to, only the states it checks (Sample::index a multiple of kStride).
  std::int64_t sample_stride() const override { return next() ? std::gcd(kStride, next()->sample_stride()) : kStride; }
  // Writes what was found into the run's summary (force_bounds, mechanical).
  void record_into(RunSummary& s) const;

 private:
  void force_bound(const Sample& s);
  void energy(const Sample& s);

  ForceTerms terms_;
  int n_;
  double alpha_;
  bool has_potential_;
  std::vector<double> grad_, force_;
  ForceBoundTrack force_bounds_;
  MechanicalEnergyTrack mechanical_;
};

}  // namespace moreau::scene

// A compiled Lagrangian scene as a model of the ABL integrator (see abl_integrator.h for the model
// requirements) and of the Moreau-Jean integrator (moreau_jean_integrator.h: constraints, restitution,
// potential). evaluate() runs one tape for every non-constant entry of M, C and g = grad V + F and
// writes the values over the constant parts; constraints() runs one tape for the gaps h_i(q) and their
// exact gradients: no allocation, no virtual call.
#pragma once

#include <algorithm>
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
    slots_.assign(static_cast<std::size_t>(1 + 2 * n_), 0.0);
    mass_values_.assign(c_.mass_tape.num_outputs(), 0.0);
    scratch_.assign(std::max({c_.mass_tape.scratch_size(), c_.potential_tape.scratch_size(), c_.constraint_tape.scratch_size()}), 0.0);
    constraint_values_.assign(c_.constraint_tape.num_outputs(), 0.0);
    wire_step_tape();
    for (const auto& targets : c_.mass_targets) {
      mass_begin_.push_back(static_cast<int>(mass_index_.size()));
      for (int t : targets) mass_index_.push_back(t);
    }
    mass_begin_.push_back(static_cast<int>(mass_index_.size()));
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
  bool constant_terms() const { return !c_.robot && !has_step_tape_; }

  void evaluate(double t, const Vec<N>& q, const Vec<N>& v, LagrangianTerms<N>& out) {
    out.g = constant_.g;
    if (c_.robot) {
      // M, C and G = grad V of gravity from the robot (rigid_body.h); the step tape below writes F (and a
      // potential's gradient) into g, and G is added after it.
      rigid_body_terms(*c_.robot, *robot_data_, q.data(), v.data(), out.M, out.C, gravity_);
    } else {
      out.M = constant_.M;
      out.C = constant_.C;
    }
    if (has_step_tape_) run_step_tape(t, q, v, out);  // none when everything is constant
    if (c_.robot) out.g += gravity_;
  }

  int num_constraints() const { return c_.num_constraints; }
  double restitution(int i) const { return restitution_[i]; }
  bool has_potential() const { return c_.has_potential; }

  double potential(const Vec<N>& q) {
    double value = 0.0;
    if (c_.potential_tape.num_outputs() > 0) {
      for (int i = 0; i < n_; ++i) slots_[1 + i] = q(i);
      c_.potential_tape.eval(slots_.data(), &value, scratch_.data());
    }
    if (c_.robot) value += potential_energy(*c_.robot, *robot_data_, q.data());
    return value;
  }

  // gap(i) = h_i(q), H.row(i) = grad h_i(q)^T.
  template <class Rows>
  void constraints(const Vec<N>& q, Eigen::VectorXd& gap, Rows& H) {
    const int m = c_.num_constraints;
    if (m == 0) return;
    for (int i = 0; i < n_; ++i) slots_[1 + i] = q(i);
    c_.constraint_tape.eval(slots_.data(), constraint_values_.data(), scratch_.data());
    for (int i = 0; i < m; ++i) {
      gap(i) = constraint_values_[i];
      for (int j = 0; j < n_; ++j) H(i, j) = constraint_values_[m + i * n_ + j];
    }
  }

  void mass(const Vec<N>& q, Mat<N>& M) {
    if (c_.robot) {
      mass_matrix(*c_.robot, *robot_data_, q.data(), M);
      return;
    }
    M = constant_.M;
    if (mass_values_.empty()) return;
    for (int i = 0; i < n_; ++i) slots_[1 + i] = q(i);
    c_.mass_tape.eval(slots_.data(), mass_values_.data(), scratch_.data());
    for (std::size_t j = 0; j + 1 < mass_begin_.size(); ++j)
      for (int k = mass_begin_[j]; k < mass_begin_[j + 1]; ++k) M.data()[mass_index_[k]] = mass_values_[j];
  }

 private:
  // The step tape runs in a scratch of its own: its constants are loaded once, t, q and v are written
  // straight into the registers it reads, and its outputs are read from their registers into M, C and g
  // (the flat index of step_targets split by matrix), with no copy through a slot or an output array.
  void wire_step_tape() {
    const expr::Tape& tape = c_.step_tape;
    has_step_tape_ = tape.num_outputs() > 0;
    step_scratch_.assign(tape.scratch_size(), 0.0);
    tape.load_constants(step_scratch_.data());
    t_register_ = tape.input_register(0);
    for (int i = 0; i < n_; ++i) {
      if (const int r = tape.input_register(1 + i); r >= 0) q_registers_.push_back({r, i});
      if (const int r = tape.input_register(1 + n_ + i); r >= 0) v_registers_.push_back({r, i});
    }
    const int nn = n_ * n_;
    for (std::size_t j = 0; j < c_.step_targets.size(); ++j) {
      const int r = tape.output_register(j);
      for (int idx : c_.step_targets[j]) {
        if (idx < nn)
          to_M_.push_back({r, idx});
        else if (idx < 2 * nn)
          to_C_.push_back({r, idx - nn});
        else
          to_g_.push_back({r, idx - 2 * nn});
      }
    }
  }

  // Runs the step tape and writes its values over the constant parts of M, C and g.
  void run_step_tape(double t, const Vec<N>& q, const Vec<N>& v, LagrangianTerms<N>& out) {
    double* s = step_scratch_.data();
    if (t_register_ >= 0) s[t_register_] = t;
    for (const Wire& w : q_registers_) s[w.reg] = q(w.index);
    for (const Wire& w : v_registers_) s[w.reg] = v(w.index);
    c_.step_tape.run(s);
    for (const Wire& w : to_M_) out.M.data()[w.index] = s[w.reg];
    for (const Wire& w : to_C_) out.C.data()[w.index] = s[w.reg];
    for (const Wire& w : to_g_) out.g.data()[w.index] = s[w.reg];
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
  std::vector<double> slots_, mass_values_, scratch_, constraint_values_;
  std::vector<int> mass_begin_, mass_index_;
  // The step tape's wiring (wire_step_tape): a register of its scratch and an index of q, v, M, C or g.
  struct Wire {
    int reg;
    int index;
  };
  bool has_step_tape_ = false;
  std::vector<double> step_scratch_;
  int t_register_ = -1;
  std::vector<Wire> q_registers_, v_registers_, to_M_, to_C_, to_g_;
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

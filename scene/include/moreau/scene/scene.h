// The scene format (docs/scene-format.md): JSON -> a validated, compiled model plus the integrator
// settings. Two system types: "lagrangian" (eq. 0.1 of Adly, Brogliato and Le 2016, optionally with the
// unilateral constraints of eq. 8 of Brogliato 2003) and "lure" (eq. 4 of Brogliato 2003). Every error
// names the JSON pointer of the field it is about.
#pragma once

#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "moreau/core/abl_integrator.h"
#include "moreau/core/absolute_stability.h"
#include "moreau/core/controller.h"
#include "moreau/core/lure_integrator.h"
#include "moreau/core/maximal_monotone_graph.h"
#include "moreau/core/moreau_jean_integrator.h"
#include "moreau/core/regularization.h"
#include "moreau/core/observer.h"
#include "moreau/core/run_diagnostics.h"
#include "moreau/core/large_abl_system.h"
#include "moreau/core/large_contact_system.h"
#include "moreau/core/rigid_body.h"
#include "moreau/core/run_summary.h"
#include "moreau/core/spline_reference.h"
#include "moreau/core/tracking.h"
#include "moreau/expr/expression.h"
#include "moreau/scene/scheme.h"

namespace moreau::scene {

// Largest step count a scene may ask for (fixed rule) or allow (adaptive rules): 2e9 steps is about
// 10 minutes of the manipulator at 300 ns per step. /integrator/max_steps may lower it, not raise it.
inline constexpr std::int64_t kMaxStepsLimit = 2'000'000'000;
// Largest number of degrees of freedom of the dense step (every scheme; a URDF robot). A scene beyond it
// (up to kMaxLargeContactDof) runs on a path at scale, which needs its structure: the large-contact path
// (large_contact_integrator.h: constant diagonal M, linear potential, gaps of a few coordinates, constant
// forces, no controller, moreau-jean) or the large ABL path (large_abl_integrator.h: constant sparse M,
// potential terms of a few coordinates, constant forces, a separable controller, no constraints, abl).
inline constexpr int kMaxDof = 64;
// Largest number of unilateral constraints of the dense step (and of Lur'e outputs); up to
// kMaxLargeContacts on the large-contact path.
inline constexpr int kMaxConstraints = 64;
// From this many coordinates a scene that has the large-contact structure runs on that path even within
// the dense limits: measured crossover of the two steps (docs/scaling.md).
inline constexpr int kLargeContactFromDof = 8;
static_assert(kMaxLargeAblDof == kMaxLargeContactDof, "one limit of coordinates for both paths at scale");

class SceneError : public std::runtime_error {
 public:
  SceneError(std::string pointer, const std::string& reason)
      : std::runtime_error((pointer.empty() ? std::string("/") : pointer) + ": " + reason),
        pointer_(pointer.empty() ? "/" : std::move(pointer)),
        reason_(reason) {}
  const std::string& pointer() const { return pointer_; }
  const std::string& reason() const { return reason_; }

 private:
  std::string pointer_;
  std::string reason_;
};

// Applies one `--set PATH=VALUE` override. PATH is dotted (integrator.h, system.mass.0.1) or a JSON
// pointer (/integrator/h). VALUE is parsed as JSON; if it is not valid JSON it is taken as a string, so
// `--set system.potential=sin(q1)` works. Missing object members are created; array indices must exist.
void apply_override(nlohmann::json& doc, const std::string& assignment);

// A key as one token of a JSON pointer (RFC 6901: '~' becomes "~0", '/' becomes "~1").
std::string json_pointer_token(std::string_view key);

// Largest scene file read_scene_file reads. It reads at most this many bytes plus one whatever the file
// is (a FIFO or a device such as /dev/zero has no size to trust): larger input is refused, not read.
inline constexpr std::size_t kMaxSceneFileBytes = std::size_t{64} << 20;  // 64 MiB

// Reads a scene file of at most kMaxSceneFileBytes and parses it with parse_json_text.
nlohmann::json read_scene_file(const std::string& path);

// Parses JSON text; `source` names it in messages ("scene file 'a.json'"). Every failure is a SceneError:
// nesting deeper than kMaxJsonDepth, a syntax error (line, column), or a number that overflows a double
// ("1e999"), reported at that number's JSON pointer with its byte offset, line and column.
nlohmann::json parse_json_text(std::string_view text, const std::string& source);

// JSON nesting allowed in a scene file, an override value or a request body. nlohmann::json copies,
// compares, prints and destroys documents recursively, so a document nested 100000 deep would overflow
// the stack long after parsing: depth is checked on the text, before parsing. A scene needs about 5.
constexpr int kMaxJsonDepth = 64;

// The byte offset of the first '[' or '{' (outside strings) that opens a level deeper than
// `max_depth`, or nullopt. Linear, no allocation; the text need not be valid JSON.
std::optional<std::size_t> json_depth_exceeded(std::string_view text, int max_depth = kMaxJsonDepth);

// The compiled expressions of a Lagrangian scene: one tape for everything a step needs, one for M(q)
// alone (the Theorem 4.2 rule) and one for V(q). Inputs of every tape: [t, q_1..q_n, v_1..v_n].
struct CompiledLagrangian {
  int n = 0;
  // step_tape and mass_tape are wired (Tape::run_wired) to these arrays: they read t, q and v where the
  // model holds them and write their outputs straight into M, C and g (column-major M and C).
  enum Source : std::int32_t { kTime, kPosition, kVelocity };
  enum Sink : std::int32_t { kMass, kCoriolis, kForce, kPotential };
  expr::Tape step_tape;  // the non-constant entries of M, C and g = grad V + F
  expr::Tape mass_tape;  // the non-constant entries of M
  // V(q), if the scene gives a potential. Wired (Tape::run_wired) to read q from sources[0] and write V to
  // sinks[0][0].
  expr::Tape potential_tape;
  // If the scene gives a potential: step_tape's outputs and V(q) last, wired as step_tape with V written
  // to sinks[kPotential][0]. The Moreau-Jean step needs M, C, g and V at every Q^{k+1} (the
  // Lagrange-Dirichlet check); in one tape V shares the sines, cosines and products of M and grad V.
  expr::Tape step_potential_tape;
  // grad V(q) (n outputs) then F(t, q, v) (n outputs), apart: Assumption 4.1 2)-3) at the recorded states.
  // Wired to read t, q and v from sources[kTime, kPosition, kVelocity] and to write grad V to sinks[0] and
  // F to sinks[1] (ForceTerms::split).
  expr::Tape split_force_tape;
  bool has_potential = false;
  bool constant_mass = true;
  // M and C are identically zero beyond this distance from the diagonal (0: diagonal), over all states:
  // no tape writes there and every constant there is 0. AblSettings::bandwidth takes it.
  int bandwidth = 0;
  // Constant parts, as flat arrays: M (n*n, column-major), C (n*n), g (n).
  std::vector<double> constant_terms;
  // A scene compiled with free parameters (ParametricLagrangianScene): the entries of [M | C | g] of the
  // parameters alone, output j going to the flat indices bound_targets[j] of constant_terms when the
  // parameters are bound. Empty otherwise.
  expr::Tape bound_terms_tape;
  std::vector<std::vector<int>> bound_targets;
  // Unilateral constraints: outputs h_1..h_m(q), then the exact gradients dh_i/dq_j (row-major, m x n).
  // Wired to read q from sources[0] and to write h_i to sinks[0][i] and dh_i/dq_j to sinks[1][i + j m]:
  // the gap vector and the m x n gradient matrix H (column-major) of the Moreau-Jean step, in place.
  int num_constraints = 0;
  expr::Tape constraint_tape;
  // Lemma 3's second-order condition: the exact Hessians of V, then of h_1..h_m, each n x n row-major.
  // Compiled only for an expression scene (no robot) with constraints, a potential and n <= kMaxHessianDof.
  static constexpr int kMaxHessianDof = 12;
  expr::Tape hessian_tape;
  // A URDF system's robot (/system/urdf): M(q), C(q, v) and the gravity part of grad V and of V come from
  // it at every evaluation (rigid_body.h); the tapes hold only what the scene adds (F, a potential).
  std::shared_ptr<const RigidBodyModel> robot;
  // Upper bounds of ||grad V(q)||_2 over every q and of ||F(t, q, v)||_2 over every (q, v) and t in
  // [t0, t_end], from interval arithmetic over the expressions (expr/interval.h); none when unbounded or
  // not enclosed (a robot's gravity, a free parameter). Assumption 4.1 2)-3) for all states rests on them.
  std::optional<double> gradient_bound, force_bound;
  // The large-contact path (large_contact_integrator.h): the system, when the scene has its structure
  // (constant diagonal M, C = 0, constant grad V + F, linear gaps, no controller, no robot). `dense`
  // false: compiled for that path alone (a scene beyond kMaxDof coordinates or kMaxConstraints
  // constraints): no dense M, C or gap gradients; constant_terms, step_tape, mass_tape and the gap
  // gradients of constraint_tape are empty, and only run_scene's large-contact route runs it.
  std::shared_ptr<const LargeContactSystem> large_contacts;
  // The large ABL path (large_abl_integrator.h): the system of a scene beyond the dense limits that runs
  // the abl scheme (constant sparse M given by its bands, a potential of terms reading a few coordinates
  // each, constant F, quadratic and abs controller terms, no constraints). `dense` is false then too.
  std::shared_ptr<const LargeAblSystem> large_abl;
  bool dense = true;
};

// V(q), grad V(q) and F(t, q, v) of a compiled scene apart, wherever they come from (the expressions, the
// robot model): for checks and reports (Assumption 4.1, energies, Lemma 3), not for the step. The tapes
// run wired to the caller's arrays, each in a scratch of its own with its constants loaded once.
class ForceTerms {
 public:
  explicit ForceTerms(const CompiledLagrangian& compiled);
  // grad_v and force: n entries each.
  void split(double t, const double* q, const double* v, double* grad_v, double* force);
  // V(q); 0 when the scene has no potential (has_potential false).
  double potential(const double* q);

 private:
  const CompiledLagrangian& c_;
  std::vector<double> split_scratch_, potential_scratch_, gravity_;
  std::unique_ptr<RigidBodyData> robot_data_;
};

// Where C(q, v) comes from (/system/coriolis): the Christoffel symbols of M, the scene's own matrix, or none.
enum class CoriolisSource { kChristoffel, kExplicit, kNone };

// The names of the options' enums, as scene files and reports spell them.
const char* to_string(CoriolisSource source);
const char* to_string(PositionUpdate update);   // "mdi", "standard"
const char* position_correction_name(bool on);  // "projection", "none"
const char* to_string(Regularization kind);     // "tanh", "saturation"
std::optional<Regularization> regularization_from_name(std::string_view name);

struct LagrangianScene;

// /system/tracking: the reference, the controller on sigma and its model of the plant (docs/tracking.md).
struct TrackingSpec {
  // The reference, one of two: expressions of t (inputs [t]; outputs q_d (n), q_d' (n), q_d'' (n), its
  // exact symbolic derivatives), or way points through which a natural cubic spline passes.
  std::shared_ptr<const expr::Tape> reference;
  std::shared_ptr<const CubicSplineReference> spline;
  std::vector<std::string> reference_text;    // q_d as written (or the way points described), for reports
  std::vector<double> lambda;                 // Lambda = diag(lambda)
  Controller<Eigen::Dynamic> phi;             // Phi on sigma
  std::optional<SampledTrackingLaw> sampled;  // empty: the continuous closed loop
  double period = 0.0;                        // T_s (sampled laws)
  double boundary_layer = 0.0;                // the saturated law's width
  double band = 0.0;                          // reaching band of a sampled law (0: the default of TrackingSettings)
  // The controller's model: the scene with /system/tracking/nominal/parameters written over its
  // parameters, without the force F, all scaled by nominal_scale.
  std::shared_ptr<const LagrangianScene> nominal;
  double nominal_scale = 1.0;
  std::vector<std::pair<std::string, double>> nominal_parameters;
  double quantum = 0.0, noise = 0.0;
  std::uint64_t seed = 1;
  std::string law_name() const { return sampled ? sampled_tracking_law_name(*sampled) : "continuous"; }
};

struct LagrangianScene {
  std::string name;
  int n = 0;
  std::vector<std::string> coordinates;  // q names
  std::vector<std::string> velocities;   // v names
  std::shared_ptr<const CompiledLagrangian> compiled;
  Controller<Eigen::Dynamic> controller;
  std::vector<double> q0, v0;
  Scheme scheme = Scheme::kAbl;
  // The time grid (settings.grid(), which every scheme runs on) and the options of the abl and explicit
  // schemes; contact_settings and the regularization below hold the other schemes' own options.
  AblSettings settings;
  CoriolisSource coriolis = CoriolisSource::kChristoffel;
  std::vector<std::string> christoffel_c;  // C(q, v) entries as text (row-major), for reports and tests; empty for URDF
  std::string robot_name;                  // the URDF's <robot name>, for a URDF system
  bool force_depends_on_time = false;      // F(t, q, v) reads t (Theorem 4.3 assumes it does not, (4.16))
  bool has_force = false;                  // /system/force given (F is taken as non-zero then)
  // grad V and F use only operations smooth on all of R^k (expr::Graph::smooth_everywhere): Assumption 3.3
  // (F locally Lipschitz uniformly in t on the run's interval, grad V locally Lipschitz) then holds.
  bool forces_smooth_everywhere = false;
  // Exact solution carried by textbook scenes (/exact), as expressions in t; empty when absent.
  std::shared_ptr<const expr::Tape> exact_tape;  // outputs q_1..q_n, v_1..v_n at slot 0 = t
  std::optional<double> exact_rest_time;
  std::vector<double> exact_rest_q;
  // Unilateral constraints h_i(q) >= 0 with Newton restitution e_i (/system/constraints), integrated by
  // the moreau-jean scheme; contact_settings carries its own options (its grid is not used: the run takes
  // settings.grid()).
  std::vector<std::string> constraint_names;
  std::vector<std::string> constraint_gaps;  // h_i(q) as text, for reports
  std::vector<double> restitution;
  MoreauJeanSettings contact_settings;
  // Parameters that no expression reads (the report warns of them: a misspelt name?).
  std::vector<std::string> unread_parameters;
  // /system/tracking, run by the tracking scheme; null otherwise.
  std::shared_ptr<const TrackingSpec> tracking;
  // The regularized scheme's sign (a study's peer): its kind and width.
  Regularization regularization = Regularization::kTanh;
  double regularization_epsilon = 1e-3;
};

// The same scene integrated by another Lagrangian scheme of the table (scheme.h), at step h, with the
// settings that scheme implies (the explicit peer: fixed step, explicit velocity update): the variants a
// study compares. Throws std::invalid_argument for a scheme of another system type.
LagrangianScene scene_variant(const LagrangianScene& scene, Scheme scheme, double h);

// Whether run_scene runs the scene on the large-contact path (large_contact_integrator.h): the
// moreau-jean scheme on a scene with that structure (CompiledLagrangian::large_contacts), beyond the
// dense limits or from kLargeContactFromDof coordinates.
bool uses_large_contact_path(const LagrangianScene& scene);
// Whether run_scene runs the scene on the large ABL path (large_abl_integrator.h): the abl scheme on a
// scene beyond the dense limits (CompiledLagrangian::large_abl).
bool uses_large_abl_path(const LagrangianScene& scene);

// Validates and compiles a Lagrangian scene. Throws SceneError naming the field (a "lure" scene gets
// one at /system/type: load it with load_lure_scene or Simulation).
LagrangianScene load_scene(const nlohmann::json& doc);

// A Lagrangian scene compiled once with some of its parameters left free, for many runs with other values
// of them (a campaign's samples) without compiling again. A free parameter is a named constant of the
// compiled expressions (expr::Tape::bind), never folded in; what depends on free parameters alone is
// computed when they are bound, with the operations constant folding uses, and the rules that fold
// constants are identities of IEEE arithmetic. So a bound scene computes, step for step, what load_scene
// compiles from the document with those values written in, bit for bit but for the sign of a zero where a
// free parameter is 0 (there the graph folds 0 * x to the constant 0: bind() refuses a 0, and callers
// compile such a sample with load_scene).
class ParametricLagrangianScene {
 public:
  // Compiles `doc` with the parameters named in `free` (under /parameters, each a finite number) left
  // free. Throws SceneError for an invalid scene, and also when it cannot be compiled so: a free
  // parameter that something needs as a number while compiling (a gain, the step, the initial state,
  // another parameter's value, an exact solution's rest time) is reported "must be constant"; and when
  // what the compiler decides from the expressions' structure (the smoothness of grad V + F, dependence
  // on t, a constant M, the band of M) differs from the compile at the document's values, or depends on
  // a free parameter's value (a free parameter in an exponent: x^p is smooth everywhere for some p only).
  ParametricLagrangianScene(const nlohmann::json& doc, std::vector<std::string> free);
  ~ParametricLagrangianScene();
  ParametricLagrangianScene(ParametricLagrangianScene&&) noexcept;

  // The scene with the free parameters at `values` (finite, non-zero, in the order of `free`; a quantity of
  // them alone that comes out 0, such as m1 - m2 at m1 = m2, is refused too: std::invalid_argument) and the
  // initial state q0, v0 (n finite numbers each), checked at the initial state as load_scene checks it
  // (SceneError naming the field: M not positive definite, a constraint violated, ...). Not safe to call
  // from two threads at once (it binds tapes it keeps for the checks). The compiled model is copied only
  // while an earlier binding's scene is still held; otherwise that model is bound again in place.
  LagrangianScene bind(const std::vector<double>& values, const std::vector<double>& q0, const std::vector<double>& v0);
  // The scene at the document's own values (its q0 and v0 are the document's).
  const LagrangianScene& nominal() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Runs the scene's scheme on its compiled model (dispatching to fixed-size code for small n): the one place
// that builds an integrator for a Lagrangian scene. Moreau-Jean also fills `contacts` when given. With
// check_recorded_states, the schemes whose row says so check Assumption 4.1 2)-3) and the energy balance
// at the recorded states (RecordedStateChecks); a study's timed runs turn that off.
RunSummary run_scene(const LagrangianScene& scene, RunObserver* observer, ContactDiagnostics* contacts = nullptr,
                     bool check_recorded_states = true);

// ---- Lur'e systems (eq. 4 of Brogliato 2003) ------------------------------------------------------------
struct LureScene {
  std::string name;
  int n = 0;                             // states
  int m = 0;                             // outputs (= feedback components)
  std::vector<std::string> states;       // x names (default x1..xn)
  std::vector<std::string> state_rates;  // <name>_dot: the discrete derivative columns
  Eigen::MatrixXd A, B, C;
  std::vector<MonotoneGraph> feedback;
  std::vector<std::string> feedback_types;  // "relay", "graph", ... per component
  std::optional<Eigen::MatrixXd> P;         // /system/P, when given
  std::vector<double> x0;
  Scheme scheme = Scheme::kImplicitEuler;
  LureSettings settings;
  // Lemmas 1-2, assumption a): the check of the given P, or the strict positive realness test without
  // one; minimality (PBH) in either case.
  StorageMatrixCheck p_check;
  PositiveRealnessTest spr;
  MinimalityCheck minimality;
  // The storage matrix of W = 1/2 x^T P x: the scene's P, or the certificate the SPR test found.
  std::optional<Eigen::MatrixXd> storage;
  std::string storage_source;  // "scene", "found" or "" (none)
  // Exact solution carried by textbook scenes (/exact): x_1..x_n as expressions in t.
  std::shared_ptr<const expr::Tape> exact_tape;
  std::optional<double> exact_rest_time;
  std::vector<double> exact_rest_x;
  // Parameters that no expression reads (the report warns of them: a misspelt name?).
  std::vector<std::string> unread_parameters;
};

// The /system/type of a scene document ("lagrangian" when absent or not a string; validation comes later).
std::string system_type(const nlohmann::json& doc);

// Validates a Lur'e scene. Throws SceneError naming the field.
LureScene load_lure_scene(const nlohmann::json& doc);

// Runs the theta-method (lure_integrator.h), dispatching to fixed-size code for n <= 4.
RunSummary run_lure_scene(const LureScene& scene, RunObserver* observer, LureDiagnostics* diagnostics);

}  // namespace moreau::scene

// The four comparison workloads of docs/siconos-comparison.md written against Siconos 4.4 (Debian 12's
// libsiconos-kernel-dev), with the step sizes, horizons and initial states of the Moreau scenes:
//
//   manipulator   scenes/manipulator.json: the cart-and-link manipulator of Adly, Brogliato and Le (2016),
//                 section 6, as a LagrangianDS (M(q), FGyr = C(q, q') q', FInt = grad V + W q', with their
//                 Jacobians) and the set-valued part of the controller, d(|v1| + |v2|), as a RelayNSL on
//                 y = q' (LagrangianLinearTIR with H = I); MoreauJeanOSI(theta = 1), Relay one-step problem,
//                 TimeStepping with its Newton loop (the model is nonlinear).
//   ball          scenes/bouncing-ball-e0.5.json: LagrangianLinearTIDS, gravity as FExt, LagrangianLinearTIR
//                 y = q, NewtonImpactNSL(e), MoreauJeanOSI(theta = 1), LCP.
//   damped-relay  scenes/damped-relay.json: m x'' = -c x' - a Sign(x'): LagrangianLinearTIDS with damping
//                 matrix c, RelayNSL on y = x', MoreauJeanOSI(theta = 1), Relay.
//   stack         scripts/make-contact-scene.py stack N: N balls resting on a floor and on each other
//                 (one LagrangianLinearTIDS per ball, an Interaction per contact), NewtonImpactNSL(0.5), LCP.
//   cradle        scripts/make-contact-scene.py cradle N --gap G: Newton's cradle, e = 1, the first ball at 1.
//   column        scripts/make-contact-scene.py column N --drop D: a granular column, N balls in a tube of
//                 width 3r dropped in a zigzag, with Siconos's mechanics module: one Disk (x, y, theta) per
//                 ball, DiskPlanR for the floor (under the first ball) and both walls (every ball), DiskDiskR
//                 between neighbours, NewtonImpactNSL(e = 0.5), MoreauJeanOSI, LCP, TimeStepping with its
//                 Newton loop (the disk-disk gaps are nonlinear). Built only when the module is installed.
//   lure-relay    scenes/lure-relay-2state.json: x' = A x - B Sign(C x): FirstOrderLinearTIDS,
//                 FirstOrderLinearTIR (y = C x, r = B lambda), RelayNSL(-1, 1), EulerMoreauOSI(theta = 1), Relay.
//
// The relay workloads on MoreauJeanOSI raise its constraint activation threshold to +inf (see
// RelayMoreauJean below): without it Siconos 4.4 drops the relay from the one-step problem every other step.
//
// With MoreauJeanOSI the one-step problem is written in impulses (v+ = v_free + W^{-1} H^T lambda, lambda
// the impulse over the step), so a relay force bounded by a is the RelayNSL bounds [-a h, a h]. With
// EulerMoreauOSI lambda is a force (x+ = x_free + h W^{-1} r), so the bounds are the gain itself.
//
// Usage: siconos_bench WORKLOAD [--h H] [--t-end T] [--reps N] [--csv FILE] [--every K]
//                               [--theta TH] [--solver NAME] [--newton nonlinear|linear] [--tol TOL]
//                               [--n N] [--gap G] [--drop D] [--e E]
// Prints one JSON object: the settings, the steps, the median/min/max time per step over --reps runs of
// the stepping loop (the model, the simulation and TimeStepping::initialize are built outside the timed
// loop and timed apart as setup), Newton iterations, the final state. --csv writes the trajectory of one
// further, untimed run (t, then positions, then velocities; or t, x1, x2), every K-th step.

// MechanicsFwd.hpp first: it adds the mechanics classes to the kernel's visitor (SICONOS_VISITABLES) before
// SiconosKernel.hpp declares it, as the mechanics library itself was compiled.
#ifdef MOREAU_SICONOS_MECHANICS
#include <MechanicsFwd.hpp>
#endif
#include <SiconosKernel.hpp>
#ifdef MOREAU_SICONOS_MECHANICS
#include <Disk.hpp>
#include <DiskDiskR.hpp>
#include <DiskPlanR.hpp>
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

namespace {

// ---- the manipulator's model (docs/numerics.md; core/include/moreau/core/models/manipulator.h) -------
// M(q) = [[m1 + m2, m2 b cos th2], [m2 b cos th2, I + m2 b^2]], q = (x1, th2)
// C(q, v) v = (-m2 b sin(th2) th2'^2, 0)            (the Christoffel C of the scene, "coriolis": "christoffel")
// grad V(q) = (0, m2 b g sin th2)                    (V = -b m2 g cos th2)
// Phi(v) = 1/2 |v|^2 + |v1| + |v2|: the quadratic part W v (W = I) is a smooth internal force, the rest the
// relay. Siconos matrices are column-major: entry (i, j) of an n x n matrix is at [i + j n].
constexpr double kM1 = 1.0, kM2 = 1.0, kB = 0.5, kI = 0.1, kG = 9.81;
constexpr double kW1 = 1.0, kW2 = 1.0;  // quadratic weights
constexpr double kA1 = 1.0, kA2 = 1.0;  // relay gains (equal: one RelayNSL of size 2 carries both)

extern "C" void manip_mass(unsigned int, double* q, double* mass, unsigned int, double*) {
  const double off = kM2 * kB * std::cos(q[1]);
  mass[0] = kM1 + kM2;
  mass[1] = off;
  mass[2] = off;
  mass[3] = kI + kM2 * kB * kB;
}
extern "C" void manip_fgyr(unsigned int, double* q, double* v, double* f, unsigned int, double*) {
  f[0] = -kM2 * kB * std::sin(q[1]) * v[1] * v[1];
  f[1] = 0.0;
}
extern "C" void manip_jac_fgyr_q(unsigned int, double* q, double* v, double* J, unsigned int, double*) {
  J[0] = 0.0;
  J[1] = 0.0;
  J[2] = -kM2 * kB * std::cos(q[1]) * v[1] * v[1];  // d f0 / d th2
  J[3] = 0.0;
}
extern "C" void manip_jac_fgyr_v(unsigned int, double* q, double* v, double* J, unsigned int, double*) {
  J[0] = 0.0;
  J[1] = 0.0;
  J[2] = -2.0 * kM2 * kB * std::sin(q[1]) * v[1];  // d f0 / d th2'
  J[3] = 0.0;
}
extern "C" void manip_fint(double, unsigned int, double* q, double* v, double* f, unsigned int, double*) {
  f[0] = kW1 * v[0];
  f[1] = kM2 * kB * kG * std::sin(q[1]) + kW2 * v[1];
}
extern "C" void manip_jac_fint_q(double, unsigned int, double* q, double*, double* J, unsigned int, double*) {
  J[0] = 0.0;
  J[1] = 0.0;
  J[2] = 0.0;
  J[3] = kM2 * kB * kG * std::cos(q[1]);
}
extern "C" void manip_jac_fint_v(double, unsigned int, double*, double*, double* J, unsigned int, double*) {
  J[0] = kW1;
  J[1] = 0.0;
  J[2] = 0.0;
  J[3] = kW2;
}

struct Options {
  std::string workload;
  double h = NAN, t_end = NAN, theta = 1.0, tol = NAN;
  int reps = 7, every = 1;
  std::string csv, solver = "default", newton = "nonlinear";
  int n = 8;          // stack, cradle, column: the number of balls
  double gap = 0.01;  // cradle: the space between neighbouring balls
  double drop = NAN;  // column: the opening of each gap at t = 0 (unset or 0: 1e-3, as the script)
  double e = NAN;     // stack, cradle, column: the restitution (unset: 0.5, 1, 0.5)
};

// One simulation ready to step: what the timed loop and the CSV writer need.
struct Built {
  SP::NonSmoothDynamicalSystem nsds;
  SP::TimeStepping sim;
  std::function<void(std::vector<double>&)> state;  // appends the state (q then v, or x)
  std::string columns;
};

SP::SiconosVector Vec(std::initializer_list<double> v) {
  auto x = std::make_shared<SiconosVector>(static_cast<unsigned>(v.size()));
  unsigned i = 0;
  for (double e : v) (*x)(i++) = e;
  return x;
}

int RelaySolverId(const std::string& name) {
  if (name == "default" || name == "avi") return SICONOS_RELAY_AVI_CAOFERRIS;
  if (name == "lemke") return SICONOS_RELAY_LEMKE;
  if (name == "enum") return SICONOS_RELAY_ENUM;
  if (name == "pgs") return SICONOS_RELAY_PGS;
  if (name == "path") return SICONOS_RELAY_PATH;
  throw std::runtime_error("unknown relay solver '" + name + "' (default, avi, lemke, enum, pgs, path)");
}

int LcpSolverId(const std::string& name) {
  if (name == "default" || name == "lemke") return SICONOS_LCP_LEMKE;
  if (name == "enum") return SICONOS_LCP_ENUM;
  if (name == "pgs") return SICONOS_LCP_PGS;
  if (name == "nsgs") return SICONOS_LCP_NSGS_SBM;
  throw std::runtime_error("unknown LCP solver '" + name + "' (default = lemke, enum, pgs, nsgs)");
}

// MoreauJeanOSI for a velocity-level relay. TimeStepping::updateIndexSet exempts a RelayNSL interaction
// from the activation test when it enters index set 1, but not from the removal test, which is the contact
// rule y + h/2 y' <= threshold (0) applied to y = H q, as if y were a gap. With y = q' the relay would be
// switched off every other step (measured: the damped relay then decelerates at 1.25 and 0.75 alternately
// instead of 1.25). An infinite threshold keeps the relay in the one-step problem at every step.
SP::MoreauJeanOSI RelayMoreauJean(double theta) {
  auto osi = std::make_shared<MoreauJeanOSI>(theta);
  osi->setConstraintActivationThreshold(std::numeric_limits<double>::infinity());
  return osi;
}

void Finish(Built& b, const Options& o, SP::OneStepIntegrator osi, SP::OneStepNSProblem osnspb) {
  auto td = std::make_shared<TimeDiscretisation>(0.0, o.h);
  b.sim = std::make_shared<TimeStepping>(b.nsds, td, osi, osnspb);
  if (o.newton == "linear")
    b.sim->setNewtonOptions(SICONOS_TS_LINEAR);
  else if (o.newton != "nonlinear")
    throw std::runtime_error("--newton is nonlinear or linear");
  if (!std::isnan(o.tol)) b.sim->setNewtonTolerance(o.tol);
  b.sim->initialize();
}

Built BuildManipulator(const Options& o) {
  Built b;
  auto ds = std::make_shared<LagrangianDS>(Vec({3.0, -1.0}), Vec({-1.0, 1.0}));
  ds->setComputeMassFunction(manip_mass);
  ds->setComputeFIntFunction(manip_fint);
  ds->setComputeFGyrFunction(manip_fgyr);
  ds->setComputeJacobianFIntqFunction(manip_jac_fint_q);
  ds->setComputeJacobianFIntqDotFunction(manip_jac_fint_v);
  ds->setComputeJacobianFGyrqFunction(manip_jac_fgyr_q);
  ds->setComputeJacobianFGyrqDotFunction(manip_jac_fgyr_v);
  ds->computeMass();

  auto H = std::make_shared<SimpleMatrix>(2, 2);  // dense I (Siconos::IDENTITY storage fails in the OSNS)
  (*H)(0, 0) = 1.0;
  (*H)(1, 1) = 1.0;
  auto relation = std::make_shared<LagrangianLinearTIR>(H);
  // Impulse bounds: the force -a Sign(v) over one step of h.
  auto nslaw = std::make_shared<RelayNSL>(2, -kA1 * o.h, kA1 * o.h);
  static_assert(kA1 == kA2, "one RelayNSL carries both gains");
  auto inter = std::make_shared<Interaction>(nslaw, relation);

  b.nsds = std::make_shared<NonSmoothDynamicalSystem>(0.0, o.t_end);
  b.nsds->insertDynamicalSystem(ds);
  b.nsds->link(inter, ds);
  auto osi = RelayMoreauJean(o.theta);
  auto osnspb = std::make_shared<Relay>(RelaySolverId(o.solver));
  Finish(b, o, osi, osnspb);
  b.state = [ds](std::vector<double>& out) {
    const SiconosVector& q = *ds->q();
    const SiconosVector& v = *ds->velocity();
    out.insert(out.end(), {q(0), q(1), v(0), v(1)});
  };
  b.columns = "t,x1,th2,x1_dot,th2_dot";
  return b;
}

Built BuildBall(const Options& o) {
  constexpr double m = 1.0, g = 9.81, e = 0.5, y0 = 1.0;
  Built b;
  auto mass = std::make_shared<SimpleMatrix>(1, 1);
  (*mass)(0, 0) = m;
  auto ds = std::make_shared<LagrangianLinearTIDS>(Vec({y0}), Vec({0.0}), mass);
  ds->setFExtPtr(Vec({-m * g}));
  auto H = std::make_shared<SimpleMatrix>(1, 1);
  (*H)(0, 0) = 1.0;
  auto relation = std::make_shared<LagrangianLinearTIR>(H);
  auto nslaw = std::make_shared<NewtonImpactNSL>(e);
  auto inter = std::make_shared<Interaction>(nslaw, relation);
  b.nsds = std::make_shared<NonSmoothDynamicalSystem>(0.0, o.t_end);
  b.nsds->insertDynamicalSystem(ds);
  b.nsds->link(inter, ds);
  auto osi = std::make_shared<MoreauJeanOSI>(o.theta);
  auto osnspb = std::make_shared<LCP>(LcpSolverId(o.solver));
  Finish(b, o, osi, osnspb);
  b.state = [ds](std::vector<double>& out) { out.insert(out.end(), {(*ds->q())(0), (*ds->velocity())(0)}); };
  b.columns = "t,y,y_dot";
  return b;
}

Built BuildDampedRelay(const Options& o) {
  constexpr double m = 2.0, c = 0.5, a = 1.0, q0 = 0.0, v0 = 3.0;
  Built b;
  auto M = std::make_shared<SimpleMatrix>(1, 1);
  (*M)(0, 0) = m;
  auto K = std::make_shared<SimpleMatrix>(1, 1);
  (*K)(0, 0) = 0.0;
  auto C = std::make_shared<SimpleMatrix>(1, 1);
  (*C)(0, 0) = c;
  auto ds = std::make_shared<LagrangianLinearTIDS>(Vec({q0}), Vec({v0}), M, K, C);
  auto H = std::make_shared<SimpleMatrix>(1, 1);
  (*H)(0, 0) = 1.0;
  auto relation = std::make_shared<LagrangianLinearTIR>(H);
  auto nslaw = std::make_shared<RelayNSL>(1, -a * o.h, a * o.h);
  auto inter = std::make_shared<Interaction>(nslaw, relation);
  b.nsds = std::make_shared<NonSmoothDynamicalSystem>(0.0, o.t_end);
  b.nsds->insertDynamicalSystem(ds);
  b.nsds->link(inter, ds);
  auto osi = RelayMoreauJean(o.theta);
  auto osnspb = std::make_shared<Relay>(RelaySolverId(o.solver));
  Finish(b, o, osi, osnspb);
  b.state = [ds](std::vector<double>& out) { out.insert(out.end(), {(*ds->q())(0), (*ds->velocity())(0)}); };
  b.columns = "t,x,x_dot";
  return b;
}

Built BuildLureRelay(const Options& o) {
  Built b;
  auto A = std::make_shared<SimpleMatrix>(2, 2);
  (*A)(0, 0) = 0.0;
  (*A)(0, 1) = 1.0;
  (*A)(1, 0) = -2.0;
  (*A)(1, 1) = -3.0;
  auto ds = std::make_shared<FirstOrderLinearTIDS>(Vec({1.0, 0.0}), A);
  auto C = std::make_shared<SimpleMatrix>(1, 2);
  (*C)(0, 0) = 1.0;
  (*C)(0, 1) = 2.0;
  auto B = std::make_shared<SimpleMatrix>(2, 1);
  (*B)(0, 0) = 0.0;
  (*B)(1, 0) = 1.0;
  // y = C x, r = B lambda, lambda in -Sign(y) (Siconos' relay: -y in N_[lb,ub](lambda)), so
  // x' = A x + B lambda = A x - B Sign(C x).
  auto relation = std::make_shared<FirstOrderLinearTIR>(C, B);
  auto nslaw = std::make_shared<RelayNSL>(1, -1.0, 1.0);
  auto inter = std::make_shared<Interaction>(nslaw, relation);
  b.nsds = std::make_shared<NonSmoothDynamicalSystem>(0.0, o.t_end);
  b.nsds->insertDynamicalSystem(ds);
  b.nsds->link(inter, ds);
  auto osi = std::make_shared<EulerMoreauOSI>(o.theta);
  auto osnspb = std::make_shared<Relay>(RelaySolverId(o.solver));
  Finish(b, o, osi, osnspb);
  b.state = [ds](std::vector<double>& out) {
    const SiconosVector& x = *ds->x();
    out.insert(out.end(), {x(0), x(1)});
  };
  b.columns = "t,x1,x2";
  return b;
}

// The contact workloads at scale (docs/scaling.md), as scripts/make-contact-scene.py writes them: one
// LagrangianLinearTIDS per ball (mass 1), one Interaction per contact, y = H q + b with H = [1] on the
// floor and [-1, 1] between neighbours, NewtonImpactNSL(e), MoreauJeanOSI, LCP (Lemke by default).
constexpr double kBallRadius = 0.0625;

Built BuildBalls(const Options& o, bool stack) {
  constexpr double g = 9.81;
  const double e = !std::isnan(o.e) ? o.e : stack ? 0.5 : 1.0;
  Built b;
  b.nsds = std::make_shared<NonSmoothDynamicalSystem>(0.0, o.t_end);
  std::vector<SP::LagrangianLinearTIDS> balls;
  for (int i = 0; i < o.n; ++i) {
    auto mass = std::make_shared<SimpleMatrix>(1, 1);
    (*mass)(0, 0) = 1.0;
    const double q0 = stack ? kBallRadius + i * 2 * kBallRadius : i * (2 * kBallRadius + o.gap);
    const double v0 = !stack && i == 0 ? 1.0 : 0.0;
    auto ds = std::make_shared<LagrangianLinearTIDS>(Vec({q0}), Vec({v0}), mass);
    if (stack) ds->setFExtPtr(Vec({-g}));
    b.nsds->insertDynamicalSystem(ds);
    balls.push_back(ds);
  }
  auto nslaw = std::make_shared<NewtonImpactNSL>(e);
  if (stack) {
    auto H = std::make_shared<SimpleMatrix>(1, 1);
    (*H)(0, 0) = 1.0;
    auto relation = std::make_shared<LagrangianLinearTIR>(H, Vec({-kBallRadius}));
    b.nsds->link(std::make_shared<Interaction>(nslaw, relation), balls[0]);
  }
  for (int i = 1; i < o.n; ++i) {
    auto H = std::make_shared<SimpleMatrix>(1, 2);
    (*H)(0, 0) = -1.0;
    (*H)(0, 1) = 1.0;
    auto relation = std::make_shared<LagrangianLinearTIR>(H, Vec({-2 * kBallRadius}));
    b.nsds->link(std::make_shared<Interaction>(nslaw, relation), balls[static_cast<std::size_t>(i - 1)],
                 balls[static_cast<std::size_t>(i)]);
  }
  auto osi = std::make_shared<MoreauJeanOSI>(o.theta);
  auto osnspb = std::make_shared<LCP>(LcpSolverId(o.solver));
  Finish(b, o, osi, osnspb);
  b.state = [balls](std::vector<double>& out) {
    for (const auto& ds : balls) out.push_back((*ds->q())(0));
    for (const auto& ds : balls) out.push_back((*ds->velocity())(0));
  };
  const char* x = stack ? "y" : "x";
  b.columns = "t";
  for (int i = 0; i < o.n; ++i) b.columns += "," + std::string(x) + std::to_string(i + 1);
  for (int i = 0; i < o.n; ++i) b.columns += "," + std::string(x) + std::to_string(i + 1) + "_dot";
  return b;
}

#ifdef MOREAU_SICONOS_MECHANICS
// DiskPlanR and DiskDiskR of Siconos 4.4 write two rows of their Jacobian, the normal and the tangent one
// (for NewtonImpactFrictionNSL, an interaction of size 2), also when the interaction has size 1 as with
// NewtonImpactNSL: SimpleMatrix's range assertion (kept in Debian's build) aborts in Simulation::initialize.
// Frictionless: Siconos's own Jacobian is computed into a two-row matrix and its normal row kept.
template <class R>
class NormalRow : public R {
 public:
  using R::R;
  void computeJachq(const BlockVector& q, BlockVector& z) override {
    SP::SimpleMatrix& jac = this->_jachq;
    if (jac->size(0) != 1) {  // a size-2 interaction: as Siconos
      R::computeJachq(q, z);
      return;
    }
    const unsigned cols = jac->size(1);
    if (!both_ || both_->size(1) != cols) both_ = std::make_shared<SimpleMatrix>(2, cols);
    std::swap(jac, both_);
    R::computeJachq(q, z);
    std::swap(jac, both_);
    for (unsigned j = 0; j < cols; ++j) (*jac)(0, j) = (*both_)(0, j);
  }

 private:
  SP::SimpleMatrix both_;
};

// The granular column (scripts/make-contact-scene.py column): ball i (from 0) at x = r (i even) or W - r
// (i odd), y = r + D + i (sqrt(3) r + D), at rest, in the tube 0 <= x <= W = 3r. Siconos's Disk has the
// coordinates (x, y, theta) and the mass matrix diag(m, m, m r^2 / 2); without friction theta stays 0.
// DiskPlanR(r, A, B, C) is the plane A x + B y + C = 0 and its gap |A x + B y + C| / hypot(A, B) - r (two
// sided; the Jacobian's sign is that of A x + B y + C), so the floor is (0, 1, 0), the left wall (1, 0, 0),
// the right wall (-1, 0, W): gaps y - r, x - r, W - x - r. DiskDiskR(r, r): hypot(dx, dy) - 2r.
Built BuildColumn(const Options& o) {
  constexpr double g = 9.81, r = kBallRadius, width = 3 * kBallRadius;
  const double e = std::isnan(o.e) ? 0.5 : o.e;
  const double drop = std::isnan(o.drop) || o.drop == 0.0 ? 1e-3 : o.drop;
  Built b;
  b.nsds = std::make_shared<NonSmoothDynamicalSystem>(0.0, o.t_end);
  std::vector<SP::Disk> balls;
  for (int i = 0; i < o.n; ++i) {
    // The same expressions as the script's q0: the same bits.
    const double x0 = i % 2 == 0 ? r : width - r;
    const double y0 = r + drop + i * (std::sqrt(3.0) * r + drop);
    auto ds = std::make_shared<Disk>(r, 1.0, Vec({x0, y0, 0.0}), Vec({0.0, 0.0, 0.0}));
    ds->setFExtPtr(Vec({0.0, -g, 0.0}));
    b.nsds->insertDynamicalSystem(ds);
    balls.push_back(ds);
  }
  auto nslaw = std::make_shared<NewtonImpactNSL>(e);
  // Each interaction with the scene's formula for its gap at t = 0, checked below.
  std::vector<std::pair<SP::Interaction, double>> contacts;
  // DiskPlanR(r, A, B, C) leaves its member width uninitialised and tests it (not +inf, its argument) to
  // decide whether the plane is a finite segment: on reused heap memory (the second model built in this
  // process) a wall became a segment with a garbage centre and balls left the tube. The constructor with
  // a point (xc, yc) on the line and the width +inf sets it.
  constexpr double inf = std::numeric_limits<double>::infinity();
  auto plane = [&](int i, double A, double B, double C, double xc, double gap0) {
    auto inter = std::make_shared<Interaction>(nslaw, std::make_shared<NormalRow<DiskPlanR>>(r, A, B, C, xc, 0.0, inf));
    b.nsds->link(inter, balls[static_cast<std::size_t>(i)]);
    contacts.emplace_back(inter, gap0);
  };
  if (o.n > 0) plane(0, 0.0, 1.0, 0.0, 0.0, balls[0]->getQ(1) - r);  // the floor, y = 0
  for (int i = 0; i < o.n; ++i) {
    const double x = balls[static_cast<std::size_t>(i)]->getQ(0);
    plane(i, 1.0, 0.0, 0.0, 0.0, x - r);               // the left wall, x = 0
    plane(i, -1.0, 0.0, width, width, width - r - x);  // the right wall, x = W
  }
  for (int i = 0; i + 1 < o.n; ++i) {
    const auto& p = balls[static_cast<std::size_t>(i)];
    const auto& q = balls[static_cast<std::size_t>(i + 1)];
    auto inter = std::make_shared<Interaction>(nslaw, std::make_shared<NormalRow<DiskDiskR>>(r, r));
    b.nsds->link(inter, p, q);
    const double dx = q->getQ(0) - p->getQ(0), dy = q->getQ(1) - p->getQ(1);
    contacts.emplace_back(inter, std::sqrt(dx * dx + dy * dy) - 2 * r);
  }
  auto osi = std::make_shared<MoreauJeanOSI>(o.theta);
  auto osnspb = std::make_shared<LCP>(LcpSolverId(o.solver));
  Finish(b, o, osi, osnspb);
  // Siconos's gaps at t = 0 against the scene's formulas, in every model built (a few microseconds of the
  // setup time): a wrong plane convention or sign, or the DiskPlanR width above, would show here. They
  // agree to 3e-17 (hypot against sqrt).
  for (const auto& [inter, gap0] : contacts) {
    inter->computeOutput(0.0, 0);
    const double y = (*inter->y(0))(0);
    if (!(std::fabs(y - gap0) <= 1e-15))
      throw std::runtime_error("column: a Siconos gap at t = 0 is " + std::to_string(y) + ", the scene's " + std::to_string(gap0));
  }
  // The state as the Moreau scene's coordinates (x1, y1, x2, y2, ...), then their velocities; theta and
  // its velocity (identically 0 without friction, and no coordinate of the scene) are left out.
  b.state = [balls](std::vector<double>& out) {
    for (const auto& ds : balls) out.insert(out.end(), {ds->getQ(0), ds->getQ(1)});
    for (const auto& ds : balls) out.insert(out.end(), {ds->getVelocity(0), ds->getVelocity(1)});
  };
  b.columns = "t";
  for (int i = 1; i <= o.n; ++i) b.columns += ",x" + std::to_string(i) + ",y" + std::to_string(i);
  for (int i = 1; i <= o.n; ++i) b.columns += ",x" + std::to_string(i) + "_dot,y" + std::to_string(i) + "_dot";
  return b;
}
#endif

constexpr const char* kWorkloads = "manipulator, ball, damped-relay, lure-relay, stack, cradle, column";

Built Build(const Options& o) {
  if (o.workload == "stack") return BuildBalls(o, true);
  if (o.workload == "cradle") return BuildBalls(o, false);
  if (o.workload == "manipulator") return BuildManipulator(o);
  if (o.workload == "ball") return BuildBall(o);
  if (o.workload == "damped-relay") return BuildDampedRelay(o);
  if (o.workload == "lure-relay") return BuildLureRelay(o);
#ifdef MOREAU_SICONOS_MECHANICS
  if (o.workload == "column") return BuildColumn(o);
#else
  if (o.workload == "column")
    throw std::runtime_error(
        "the column workload needs Siconos's mechanics module (libsiconos-mechanics-dev): "
        "siconos_bench was built without it");
#endif
  throw std::runtime_error("unknown workload '" + o.workload + "' (" + kWorkloads + ")");
}

void Defaults(Options& o) {
  // The Moreau scenes' h and t_end.
  struct D {
    const char* name;
    double h, t_end;
  };
  const D table[] = {{"manipulator", 1e-3, 10.0}, {"ball", 1e-3, 3.0},   {"damped-relay", 1e-3, 6.0}, {"lure-relay", 1e-3, 10.0},
                     {"stack", 1e-3, 1.0},        {"cradle", 1e-3, NAN}, {"column", 1e-3, 1.0}};
  if (o.workload == "cradle" && std::isnan(o.t_end)) o.t_end = (o.n - 1) * o.gap + 0.05;  // the wave, then 50 steps
  for (const D& d : table) {
    if (o.workload == d.name) {
      if (std::isnan(o.h)) o.h = d.h;
      if (std::isnan(o.t_end)) o.t_end = d.t_end;
    }
  }
}

long Steps(const Options& o) { return std::lround(o.t_end / o.h); }

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

using Clock = std::chrono::steady_clock;

void Usage() {
  std::fprintf(stderr,
               "usage: siconos_bench manipulator|ball|damped-relay|lure-relay|stack|cradle|column [--h H] [--t-end T] [--reps N]\n"
               "       [--n N] [--gap G] [--drop D] [--e E]  (stack, cradle, column: N balls; cradle: G apart;\n"
               "       column: each gap opened by D at t = 0, default 1e-3; E the restitution, default 0.5, cradle 1)\n"
               "       [--csv FILE] [--every K] [--theta TH] [--solver NAME] [--newton nonlinear|linear] [--tol TOL]\n");
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  if (argc < 2) {
    Usage();
    return 2;
  }
  o.workload = argv[1];
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        Usage();
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--h")
      o.h = std::stod(next());
    else if (a == "--t-end")
      o.t_end = std::stod(next());
    else if (a == "--reps")
      o.reps = std::stoi(next());
    else if (a == "--csv")
      o.csv = next();
    else if (a == "--every")
      o.every = std::stoi(next());
    else if (a == "--theta")
      o.theta = std::stod(next());
    else if (a == "--solver")
      o.solver = next();
    else if (a == "--newton")
      o.newton = next();
    else if (a == "--tol")
      o.tol = std::stod(next());
    else if (a == "--n")
      o.n = std::stoi(next());
    else if (a == "--gap")
      o.gap = std::stod(next());
    else if (a == "--drop")
      o.drop = std::stod(next());
    else if (a == "--e")
      o.e = std::stod(next());
    else {
      Usage();
      return 2;
    }
  }
  try {
    Defaults(o);
    if (std::isnan(o.h)) throw std::runtime_error("unknown workload '" + o.workload + "' (" + kWorkloads + ")");
    const long steps = Steps(o);
    std::vector<double> step_ns, setup_us;
    unsigned long newton_total = 0;
    std::vector<double> final_state;
    // One untimed warm-up run, then --reps timed runs (none at all with --reps 0, e.g. for a reference).
    for (int rep = o.reps > 0 ? -1 : 0; rep < o.reps; ++rep) {
      const auto t0 = Clock::now();
      Built b = Build(o);
      const auto t1 = Clock::now();
      for (long k = 0; k < steps; ++k) {
        b.sim->computeOneStep();
        b.sim->nextStep();
      }
      const auto t2 = Clock::now();
      if (rep < 0) continue;
      setup_us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
      step_ns.push_back(std::chrono::duration<double, std::nano>(t2 - t1).count() / static_cast<double>(steps));
      newton_total = b.sim->getNewtonCumulativeNbIterations();
      final_state.clear();
      b.state(final_state);
    }
    if (!o.csv.empty()) {
      Built b = Build(o);
      std::ofstream out(o.csv);
      out.precision(17);
      out << b.columns << "\n";
      std::vector<double> s;
      auto row = [&](double t) {
        s.clear();
        b.state(s);
        out << t;
        for (double x : s) out << "," << x;
        out << "\n";
      };
      row(0.0);
      for (long k = 0; k < steps; ++k) {
        b.sim->computeOneStep();
        b.sim->nextStep();
        if ((k + 1) % o.every == 0 || k + 1 == steps) row(static_cast<double>(k + 1) * o.h);
      }
    }
    std::ostringstream js;
    js.precision(10);
    js << "{\"workload\": \"" << o.workload << "\", \"n\": " << o.n << ", \"h\": " << o.h << ", \"t_end\": " << o.t_end
       << ", \"theta\": " << o.theta << ", \"solver\": \"" << o.solver << "\", \"newton\": \"" << o.newton << "\", \"steps\": " << steps
       << ", \"reps\": " << o.reps;
    if (!step_ns.empty()) {
      js << ", \"ns_per_step\": " << Median(step_ns) << ", \"ns_per_step_min\": " << *std::min_element(step_ns.begin(), step_ns.end())
         << ", \"ns_per_step_max\": " << *std::max_element(step_ns.begin(), step_ns.end()) << ", \"setup_us\": " << Median(setup_us)
         << ", \"newton_iterations\": " << newton_total << ", \"final\": [";
      for (size_t i = 0; i < final_state.size(); ++i) js << (i ? ", " : "") << final_state[i];
      js << "]";
    }
    js << "}";
    std::cout << js.str() << std::endl;
  } catch (Siconos::exception& e) {
    std::cerr << "siconos_bench: Siconos exception: " << boost::diagnostic_information(e) << std::endl;
    return 1;
  } catch (std::exception& e) {
    std::cerr << "siconos_bench: " << e.what() << std::endl;
    return 1;
  }
  return 0;
}

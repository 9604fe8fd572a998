// Per-solve cost of the one-step generalized equation u + D w = q, w_i in G_i(u_i)
// (core/include/moreau/core/graph_inclusion_solver.h), by route: the active-set iteration followed by
// path following (the solver's default), and the same followed by the former fallback (every pattern up
// to 3^10, then forward-backward splitting). The problems: m relay rows (three pieces each) with D a
// P-matrix of the kind that makes the active-set iteration cycle (positive definite symmetric part, a
// skew part of the same size), q random. "all" solves 256 problems in turn; "cycling" only those of them
// where the active-set iteration did not finish (the steps that used to cost milliseconds). Each solve is
// timed on its own (its fastest of the rounds, see Run): the counters are the median and the worst
// problem in microseconds, their ratio, and the share of solves that needed the fallback. Table and command: docs/numerics.md, "The graph
// inclusion solver's fallback".
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <random>
#include <vector>

#include "moreau/core/graph_inclusion_solver.h"
#include "moreau/core/maximal_monotone_graph.h"
#include "moreau/core/one_step_solver.h"

namespace {

using namespace moreau;
using Solver = GraphInclusionSolver<Eigen::Dynamic>;

struct Problem {
  Eigen::MatrixXd D;
  Eigen::VectorXd q;
};

const MonotoneGraph& Relay() {
  static const MonotoneGraph relay = MonotoneGraph::relay(1.0);
  return relay;
}

// 256 problems of m relay rows; cycling: only those the active-set iteration does not finish.
std::vector<Problem> Problems(int m, bool cycling) {
  std::vector<Problem> out;
  std::mt19937 rng(static_cast<unsigned>(1000 + m));
  std::normal_distribution<double> N(0.0, 1.0);
  std::vector<const MonotoneGraph*> g(m, &Relay());
  Solver probe;
  probe.configure(m);
  for (int k = 0; out.size() < 256 && k < 100000; ++k) {
    const Eigen::MatrixXd R = Eigen::MatrixXd::NullaryExpr(m, m, [&] { return N(rng); });
    const Eigen::MatrixXd K = Eigen::MatrixXd::NullaryExpr(m, m, [&] { return N(rng); });
    Problem p{R * R.transpose() / m + 0.2 * Eigen::MatrixXd::Identity(m, m) + (K - K.transpose()),
              Eigen::VectorXd::NullaryExpr(m, [&] { return 2.0 * N(rng); })};
    if (cycling) {
      Solver fresh;  // no warm start: whether the iteration from the decoupled guess finishes
      fresh.configure(m);
      Eigen::VectorXd u(m), w(m);
      GraphSolveStats st;
      fresh.solve(p.D, p.q, g.data(), u, w, st);
      if (!st.used_fallback) continue;
    }
    out.push_back(std::move(p));
  }
  return out;
}

// Each iteration solves every problem once, in order (so each one's warm start, the previous problem's
// pattern, is the same in every round). A problem's time is its fastest round: the cost of the solve
// itself, without the preemptions of a shared machine, which the slowest round shows instead.
void Run(benchmark::State& state, Solver::Fallback fallback, bool cycling) {
  const int m = static_cast<int>(state.range(0));
  const std::vector<Problem> problems = Problems(m, cycling);
  const std::size_t n = problems.size();
  std::vector<const MonotoneGraph*> g(m, &Relay());
  Solver solver;
  solver.configure(m);
  solver.set_fallback(fallback);
  Eigen::VectorXd u(m), w(m);
  std::vector<double> fastest(n, 1e300), slowest(n, 0.0);
  long fell_back = 0, solves = 0;
  double worst_residual = 0.0;
  for (auto _ : state) {
    for (std::size_t k = 0; k < n; ++k) {
      const Problem& p = problems[k];
      GraphSolveStats st;
      const auto t0 = std::chrono::steady_clock::now();
      const bool ok = solver.solve(p.D, p.q, g.data(), u, w, st);
      const auto t1 = std::chrono::steady_clock::now();
      if (!ok) {
        state.SkipWithError("a solve was not accepted");
        return;
      }
      benchmark::DoNotOptimize(w.data());
      const double us = std::chrono::duration<double, std::micro>(t1 - t0).count();
      fastest[k] = std::min(fastest[k], us);
      slowest[k] = std::max(slowest[k], us);
      fell_back += st.used_fallback;
      ++solves;
      worst_residual = std::max(worst_residual, st.residual / std::max(st.tolerance, 1e-300));
    }
  }
  state.SetItemsProcessed(solves);
  std::vector<double> sorted = fastest;
  std::sort(sorted.begin(), sorted.end());
  const double median = sorted[n / 2], worst = sorted.back();
  state.counters["problems"] = static_cast<double>(n);
  state.counters["median_us"] = median;
  state.counters["worst_us"] = worst;
  state.counters["worst/median"] = worst / median;
  state.counters["slowest_round_us"] = *std::max_element(slowest.begin(), slowest.end());
  state.counters["fallback_share"] = static_cast<double>(fell_back) / static_cast<double>(solves);
  state.counters["residual/tol"] = worst_residual;  // <= 1: every answer accepted at round-off
}

void BM_GraphSolve_all_path(benchmark::State& s) { Run(s, Solver::Fallback::kPath, false); }
void BM_GraphSolve_all_enumeration(benchmark::State& s) { Run(s, Solver::Fallback::kEnumeration, false); }
void BM_GraphSolve_cycling_path(benchmark::State& s) { Run(s, Solver::Fallback::kPath, true); }
void BM_GraphSolve_cycling_enumeration(benchmark::State& s) { Run(s, Solver::Fallback::kEnumeration, true); }

// The ABL one-step problem (6.5) with the norm term of Remark 4.2: P y + x in -d phi(y), phi(y) =
// sum_i |y_i| + 0.5 ||y||, on 256 problems of the kind above (P = R R^T / n + 0.2 I + a skew part). Where
// the sign-pattern iteration cycles, the fallback is the search over the radius ||y||
// (one_step_solver.h), which replaced the enumeration of 3^n patterns (n <= 10; 9.7 ms mean per solve at
// n = 10). Counters as above.
void BM_OneStepNormTerm(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  std::mt19937 rng(static_cast<unsigned>(2000 + n));
  std::normal_distribution<double> N(0.0, 1.0);
  std::vector<std::pair<Eigen::MatrixXd, Eigen::VectorXd>> problems;
  for (int k = 0; k < 256; ++k) {
    const Eigen::MatrixXd R = Eigen::MatrixXd::NullaryExpr(n, n, [&] { return N(rng); });
    const Eigen::MatrixXd K = Eigen::MatrixXd::NullaryExpr(n, n, [&] { return N(rng); });
    problems.emplace_back(R * R.transpose() / n + 0.2 * Eigen::MatrixXd::Identity(n, n) + (K - K.transpose()),
                          Eigen::VectorXd::NullaryExpr(n, [&] { return 2.0 * N(rng); }));
  }
  OneStepSolver<Eigen::Dynamic> solver;
  solver.configure(Eigen::VectorXd::Ones(n), 0.5);
  Eigen::VectorXd y(n);
  std::vector<double> fastest(problems.size(), 1e300);
  long fell_back = 0, solves = 0;
  for (auto _ : state) {
    for (std::size_t k = 0; k < problems.size(); ++k) {
      OneStepStats st;
      const auto t0 = std::chrono::steady_clock::now();
      const bool ok = solver.solve(problems[k].first, problems[k].second, y, st);
      const auto t1 = std::chrono::steady_clock::now();
      if (!ok) {
        state.SkipWithError("a solve was not accepted");
        return;
      }
      benchmark::DoNotOptimize(y.data());
      fastest[k] = std::min(fastest[k], std::chrono::duration<double, std::micro>(t1 - t0).count());
      fell_back += st.used_fallback;
      ++solves;
    }
  }
  state.SetItemsProcessed(solves);
  std::vector<double> sorted = fastest;
  std::sort(sorted.begin(), sorted.end());
  state.counters["median_us"] = sorted[sorted.size() / 2];
  state.counters["worst_us"] = sorted.back();
  state.counters["worst/median"] = sorted.back() / sorted[sorted.size() / 2];
  state.counters["fallback_share"] = static_cast<double>(fell_back) / static_cast<double>(solves);
}

}  // namespace

BENCHMARK(BM_OneStepNormTerm)->Arg(4)->Arg(10)->Arg(16)->Arg(40)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_GraphSolve_all_path)->Arg(4)->Arg(8)->Arg(10)->Arg(12)->Arg(16)->Arg(32)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_GraphSolve_all_enumeration)->Arg(4)->Arg(8)->Arg(10)->Arg(12)->Arg(16)->Arg(32)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_GraphSolve_cycling_path)->Arg(4)->Arg(8)->Arg(10)->Arg(12)->Arg(16)->Arg(32)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_GraphSolve_cycling_enumeration)->Arg(4)->Arg(8)->Arg(10)->Arg(12)->Arg(16)->Arg(32)->Unit(benchmark::kMicrosecond);

BENCHMARK_MAIN();

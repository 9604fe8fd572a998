#include "moreau/core/absolute_stability.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <functional>
#include <limits>
#include <vector>

namespace moreau {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

double max_abs(const Eigen::MatrixXd& X) { return X.size() ? X.cwiseAbs().maxCoeff() : 0.0; }

Eigen::VectorXd sym_eigenvalues(const Eigen::MatrixXd& S) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (S + S.transpose()), Eigen::EigenvaluesOnly);
  return eig.eigenvalues();
}

// (1 + (w/wc)^2) lambda_min(G(jw) + G(jw)^H), G(jw) = C (jw I - A)^{-1} B: the sign of lambda_min, scaled
// so that its high-frequency limit is finite (G + G^H decays like 1/w^2 for a strictly proper G).
double frequency_eigenvalue(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C, double w, double wc) {
  const int n = static_cast<int>(A.rows());
  Eigen::MatrixXcd Z = -A.cast<std::complex<double>>();
  for (int i = 0; i < n; ++i) Z(i, i) += std::complex<double>(0.0, w);
  const Eigen::MatrixXcd X = Z.partialPivLu().solve(B.cast<std::complex<double>>());
  const Eigen::MatrixXcd G = C.cast<std::complex<double>>() * X;
  const Eigen::MatrixXcd H = G + G.adjoint();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd> eig(H, Eigen::EigenvaluesOnly);
  return (1.0 + (w / wc) * (w / wc)) * eig.eigenvalues()(0);
}

int rank(const Eigen::MatrixXd& X) {
  Eigen::FullPivLU<Eigen::MatrixXd> lu(X);
  lu.setThreshold(1e-10);
  return static_cast<int>(lu.rank());
}

// Maximises a function of z in R^k by Nelder-Mead (restarted from the best vertex).
Eigen::VectorXd nelder_mead_max(const std::function<double(const Eigen::VectorXd&)>& f, Eigen::VectorXd z0, double step, int max_evals) {
  const int k = static_cast<int>(z0.size());
  Eigen::VectorXd best = z0;
  double fbest = f(z0);
  int evals = 1;
  for (int restart = 0; restart < 4 && evals < max_evals; ++restart) {
    std::vector<Eigen::VectorXd> x(static_cast<std::size_t>(k + 1), best);
    std::vector<double> fx(static_cast<std::size_t>(k + 1), fbest);
    for (int i = 0; i < k; ++i) {
      x[i + 1](i) += step;
      fx[i + 1] = f(x[i + 1]);
      ++evals;
    }
    for (int it = 0; it < 200 * (k + 1) && evals < max_evals; ++it) {
      std::vector<int> order(static_cast<std::size_t>(k + 1));
      for (int i = 0; i <= k; ++i) order[i] = i;
      std::sort(order.begin(), order.end(), [&](int a, int b) { return fx[a] > fx[b]; });  // best first
      const int worst = order[k];
      const double spread = std::abs(fx[order[0]] - fx[worst]);
      if (spread <= 1e-13 * (1.0 + std::abs(fx[order[0]]))) break;
      Eigen::VectorXd centroid = Eigen::VectorXd::Zero(k);
      for (int i = 0; i < k; ++i) centroid += x[order[i]];
      centroid /= k;
      const Eigen::VectorXd xr = centroid + (centroid - x[worst]);
      const double fr = f(xr);
      ++evals;
      if (fr > fx[order[0]]) {
        const Eigen::VectorXd xe = centroid + 2.0 * (centroid - x[worst]);
        const double fe = f(xe);
        ++evals;
        if (fe > fr) {
          x[worst] = xe;
          fx[worst] = fe;
        } else {
          x[worst] = xr;
          fx[worst] = fr;
        }
      } else if (fr > fx[order[k - 1]]) {
        x[worst] = xr;
        fx[worst] = fr;
      } else {
        const Eigen::VectorXd xc = centroid + 0.5 * (x[worst] - centroid);
        const double fc = f(xc);
        ++evals;
        if (fc > fx[worst]) {
          x[worst] = xc;
          fx[worst] = fc;
        } else {
          for (int i = 1; i <= k; ++i) {
            x[order[i]] = x[order[0]] + 0.5 * (x[order[i]] - x[order[0]]);
            fx[order[i]] = f(x[order[i]]);
            ++evals;
          }
        }
      }
    }
    for (int i = 0; i <= k; ++i) {
      if (fx[i] > fbest) {
        fbest = fx[i];
        best = x[i];
      }
    }
    step *= 0.25;
  }
  return best;
}

}  // namespace

StorageMatrixCheck check_storage_matrix(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C,
                                        const Eigen::MatrixXd& P) {
  StorageMatrixCheck c;
  const double pmax = std::max(max_abs(P), 1e-300);
  c.asymmetry = max_abs(P - P.transpose()) / pmax;
  c.symmetric = c.asymmetry <= 1e-12;
  const Eigen::VectorXd ev = sym_eigenvalues(P);
  c.min_eigenvalue = ev(0);
  c.positive_definite = c.min_eigenvalue > 64.0 * kEps * std::abs(ev(ev.size() - 1));
  const Eigen::MatrixXd L = P * A + A.transpose() * P;
  const Eigen::VectorXd el = sym_eigenvalues(L);
  c.max_eigenvalue_pa = el(el.size() - 1);
  c.dissipative = c.max_eigenvalue_pa < -64.0 * kEps * std::max(std::abs(el(0)), max_abs(P) * max_abs(A));
  const double scale = max_abs(B) * pmax + max_abs(C);
  c.output_residual = max_abs(B.transpose() * P - C) / std::max(scale, 1e-300);
  c.output_matches = c.output_residual <= 1e-10;
  return c;
}

PositiveRealnessTest test_strict_positive_realness(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C) {
  PositiveRealnessTest r;
  const int n = static_cast<int>(A.rows());
  const int m = static_cast<int>(B.cols());

  Eigen::EigenSolver<Eigen::MatrixXd> eig(A, false);
  r.spectral_abscissa = eig.eigenvalues().real().maxCoeff();
  r.hurwitz = r.spectral_abscissa < 0.0;
  const double rho = eig.eigenvalues().cwiseAbs().maxCoeff();

  Eigen::MatrixXd ctrb(n, n * m), obsv(n * C.rows(), n);
  Eigen::MatrixXd AkB = B, CAk = C;
  for (int k = 0; k < n; ++k) {
    ctrb.middleCols(k * m, m) = AkB;
    obsv.middleRows(k * C.rows(), C.rows()) = CAk;
    AkB = A * AkB;
    CAk = CAk * A;
  }
  r.controllable = rank(ctrb) == n;
  r.observable = rank(obsv) == n;

  const Eigen::MatrixXd CB = C * B;
  const bool cb_sym = max_abs(CB - CB.transpose()) <= 1e-12 * std::max(max_abs(CB), 1e-300);
  r.cb_min_eigenvalue = CB.rows() == CB.cols() ? sym_eigenvalues(CB)(0) : 0.0;
  r.cb_symmetric_positive = CB.rows() == CB.cols() && cb_sym && r.cb_min_eigenvalue > 0.0;
  const Eigen::MatrixXd CAB = C * A * B;
  r.high_frequency_min_eigenvalue = CAB.rows() == CAB.cols() ? sym_eigenvalues(-(CAB + CAB.transpose()))(0) : 0.0;
  r.high_frequency = CAB.rows() == CAB.cols() && r.high_frequency_min_eigenvalue > 0.0;

  // Frequency sweep.
  const double wc = std::max(1.0, rho);
  r.omega_min = 1e-6 * wc;
  r.omega_max = 1e6 * wc;
  const int K = 1201;
  double fmin = frequency_eigenvalue(A, B, C, 0.0, wc);
  double wmin = 0.0;
  int jmin = -1;
  std::vector<double> grid(K);
  for (int j = 0; j < K; ++j) {
    grid[j] = r.omega_min * std::pow(10.0, 12.0 * j / (K - 1));
    const double f = frequency_eigenvalue(A, B, C, grid[j], wc);
    if (f < fmin) {
      fmin = f;
      wmin = grid[j];
      jmin = j;
    }
  }
  r.frequencies = K + 1;
  if (jmin >= 0) {
    double a = grid[std::max(0, jmin - 1)], b = grid[std::min(K - 1, jmin + 1)];
    const double g = 0.5 * (std::sqrt(5.0) - 1.0);
    double x1 = b - g * (b - a), x2 = a + g * (b - a);
    double f1 = frequency_eigenvalue(A, B, C, x1, wc), f2 = frequency_eigenvalue(A, B, C, x2, wc);
    r.frequencies += 2;
    for (int it = 0; it < 60; ++it) {
      if (f1 < f2) {
        b = x2;
        x2 = x1;
        f2 = f1;
        x1 = b - g * (b - a);
        f1 = frequency_eigenvalue(A, B, C, x1, wc);
      } else {
        a = x1;
        x1 = x2;
        f1 = f2;
        x2 = a + g * (b - a);
        f2 = frequency_eigenvalue(A, B, C, x2, wc);
      }
      ++r.frequencies;
    }
    if (std::min(f1, f2) < fmin) {
      fmin = std::min(f1, f2);
      wmin = f1 < f2 ? x1 : x2;
    }
  }
  r.min_frequency_eigenvalue = fmin;
  r.argmin_omega = wmin;
  r.frequency = fmin > 0.0;
  r.spr = r.hurwitz && r.frequency && r.cb_symmetric_positive && r.high_frequency;
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "frequency domain (strictly proper G): A Hurwitz from its eigenvalues; (1 + (w/wc)^2) lambda_min(G(jw) + "
                "G(jw)^H) > 0 at w = 0 and %d log-spaced w in [%.3g, %.3g] (wc = %.3g), refined by golden-section search "
                "(%d evaluations of G(jw) in all); CB = (CB)^T > 0 and -(CAB + (CAB)^T) > 0 for the limit w -> infinity",
                K, r.omega_min, r.omega_max, wc, r.frequencies);
  r.method = buf;

  // A certificate P on {P = P^T, B^T P = C}.
  if (n > 12) {
    r.storage_method = "not attempted (n > 12)";
    return r;
  }
  r.storage_attempted = true;
  const int np = n * (n + 1) / 2;
  std::vector<std::pair<int, int>> idx;
  for (int i = 0; i < n; ++i)
    for (int j = i; j < n; ++j) idx.emplace_back(i, j);
  auto assemble = [&](const Eigen::VectorXd& p) {
    Eigen::MatrixXd P(n, n);
    for (int k = 0; k < np; ++k) P(idx[k].first, idx[k].second) = P(idx[k].second, idx[k].first) = p(k);
    return P;
  };
  const int rows = static_cast<int>(C.rows()) * n;
  Eigen::MatrixXd E(rows, np);
  Eigen::VectorXd c(rows);
  for (int k = 0; k < np; ++k) {
    Eigen::VectorXd e = Eigen::VectorXd::Zero(np);
    e(k) = 1.0;
    const Eigen::MatrixXd BtP = B.transpose() * assemble(e);
    E.col(k) = Eigen::Map<const Eigen::VectorXd>(BtP.data(), rows);
  }
  c = Eigen::Map<const Eigen::VectorXd>(C.data(), rows);
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(E, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::VectorXd p0 = svd.solve(c);
  if ((E * p0 - c).cwiseAbs().maxCoeff() > 1e-10 * (1.0 + c.cwiseAbs().maxCoeff())) {
    r.storage_method = "no symmetric P satisfies B^T P = C (the linear equations are inconsistent)";
    return r;
  }
  const Eigen::VectorXd sv = svd.singularValues();
  const double tol = 1e-12 * std::max(1.0, sv.size() ? sv(0) : 1.0);
  int rank_e = 0;
  for (int i = 0; i < sv.size(); ++i)
    if (sv(i) > tol) ++rank_e;
  const Eigen::MatrixXd Nul = svd.matrixV().rightCols(np - rank_e);
  auto objective = [&](const Eigen::VectorXd& z) {
    const Eigen::MatrixXd P = assemble(p0 + Nul * z);
    const double lp = sym_eigenvalues(P)(0);
    const Eigen::VectorXd el = sym_eigenvalues(-(P * A + A.transpose() * P));
    return std::min(lp, el(0));
  };
  Eigen::VectorXd z = Eigen::VectorXd::Zero(Nul.cols());
  if (Nul.cols() > 0) z = nelder_mead_max(objective, z, std::max(1.0, p0.cwiseAbs().maxCoeff()), 20000);
  r.P = assemble(p0 + Nul * z);
  r.storage_check = check_storage_matrix(A, B, C, r.P);
  r.storage_found = r.storage_check.all();
  std::snprintf(buf, sizeof buf,
                "searched the %d-dimensional affine set of symmetric P with B^T P = C for the largest "
                "min(lambda_min(P), lambda_min(-(PA + A^T P))) by Nelder-Mead: %s (margin %.3g)",
                static_cast<int>(Nul.cols()), r.storage_found ? "found" : "none found", objective(z));
  r.storage_method = buf;
  return r;
}

}  // namespace moreau

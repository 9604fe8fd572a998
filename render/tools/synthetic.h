// Synthetic nonsmooth trajectories with closed-form solutions, for the reference figures, the
// tests and the benchmark: a bouncing ball (impacts accumulating at a finite time) and a mass on a
// spring with Coulomb friction (sticks after finitely many swings).
#pragma once

#include <cmath>
#include <cstddef>
#include <numbers>
#include <vector>

#include "moreau/render/figures.h"

namespace moreau::render::synthetic {

struct Ball {
  double g = 9.81, h0 = 1.0, e = 0.8;
  double first_impact() const { return std::sqrt(2 * h0 / g); }
  // Impacts accumulate at this time; the ball rests afterwards.
  double rest_time() const { return first_impact() + 2 * g * first_impact() * e / (g * (1 - e)); }
  std::vector<double> impacts(double t_end) const {
    std::vector<double> out;
    double t = first_impact(), u = g * first_impact() * e;
    while (t < t_end && t < rest_time()) {
      out.push_back(t);
      const double flight = 2 * u / g;
      if (flight < 1e-5) break;
      t += flight;
      u *= e;
    }
    return out;
  }
  // Height and velocity at t.
  void state(double t, double& q, double& v) const {
    const double t1 = first_impact();
    if (t < t1) {
      q = h0 - 0.5 * g * t * t;
      v = -g * t;
      return;
    }
    if (t >= rest_time()) {
      q = v = 0;
      return;
    }
    double ts = t1, u = g * t1 * e;
    while (t > ts + 2 * u / g) {
      ts += 2 * u / g;
      u *= e;
    }
    const double s = t - ts;
    q = u * s - 0.5 * g * s * s;
    v = u - g * s;
  }
};

struct CoulombOscillator {
  double omega = 2 * std::numbers::pi * 0.9, friction = 3.5, x0 = 1.0;  // friction: force / mass
  void state(double t, double& q, double& v) const {
    const double k = omega * omega, band = friction / k;
    double start = x0, ts = 0;
    const double half = std::numbers::pi / omega;
    while (true) {
      if (std::abs(start) <= band) {  // stuck
        q = start;
        v = 0;
        return;
      }
      const double c = start > 0 ? band : -band;  // moving towards the origin: friction opposes
      if (t <= ts + half) {
        const double s = t - ts;
        q = c + (start - c) * std::cos(omega * s);
        v = -(start - c) * omega * std::sin(omega * s);
        return;
      }
      start = 2 * c - start;
      ts += half;
    }
  }
};

// n samples over [0, t_end] of both systems: q = {ball height, oscillator position}, v likewise.
inline TimeSeriesData trajectory(std::size_t n, double t_end = 5.0) {
  Ball ball;
  CoulombOscillator osc;
  TimeSeriesData d;
  d.q_names = {"ball height", "oscillator x"};
  d.v_names = {"ball velocity", "oscillator v"};
  d.q.assign(2, {});
  d.v.assign(2, {});
  for (auto& c : d.q) c.reserve(n);
  for (auto& c : d.v) c.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = t_end * static_cast<double>(i) / static_cast<double>(n - 1);
    double q, v;
    d.t.push_back(t);
    ball.state(t, q, v);
    d.q[0].push_back(q);
    d.v[0].push_back(v);
    d.energy.push_back(t >= ball.rest_time() ? 0.0 : ball.g * q + 0.5 * v * v);
    osc.state(t, q, v);
    d.q[1].push_back(q);
    d.v[1].push_back(v);
    d.h.push_back(t_end / static_cast<double>(n - 1));
  }
  d.h.pop_back();
  d.impact_times = ball.impacts(t_end);
  d.converged_time = ball.rest_time();
  d.energy_label = "ball energy";
  return d;
}

}  // namespace moreau::render::synthetic

// Writes the reference figures of docs/figures/ from synthetic data:
//   moreau_render_figures [output-directory]   (default: docs/figures)
#include <cmath>
#include <cstdio>
#include <string>

#include "moreau/render/figures.h"
#include "moreau/render/render.h"
#include "synthetic.h"

using namespace moreau::render;

int main(int argc, char** argv) {
  const std::string dir = argc > 1 ? argv[1] : "docs/figures";
  const TimeSeriesData d = synthetic::trajectory(20000);

  FigureOptions o;
  o.width_px = 1200;
  o.height_px = 800;
  o.title = "Bouncing ball and Coulomb oscillator";
  render_png(state_figure(d, o), dir + "/state.png");

  o.width_px = 1000;
  o.height_px = 480;
  o.title = "Energy of the bouncing ball";
  render_png(energy_figure(d, o), dir + "/energy.png");

  o.title = "Phase portrait";
  o.width_px = 800;
  o.height_px = 600;
  render_png(phase_figure(d, o), dir + "/phase.png");

  // A convergence study: error ~ C h^p with a little scatter.
  std::vector<SchemeRuns> runs;
  const struct {
    const char* name;
    double order, c, cost;
  } schemes[] = {{"Moreau-Jean", 1.0, 0.8, 1.0}, {"Schatzman-Paoli", 2.0, 2.0, 1.6}, {"ABL", 2.0, 0.3, 2.4}};
  for (const auto& s : schemes) {
    SchemeRuns r;
    r.scheme = s.name;
    for (int k = 0; k < 7; ++k) {
      const double h = 1e-1 * std::pow(2.0, -k);
      r.h.push_back(h);
      r.error.push_back(s.c * std::pow(h, s.order) * (1 + 0.08 * std::sin(3.0 * k + s.order)));
      r.run_time_s.push_back(s.cost * 2e-3 / h);
    }
    runs.push_back(r);
  }
  FigureOptions so;
  so.width_px = 900;
  so.height_px = 600;
  so.title = "Convergence order";
  render_png(order_figure(runs, so), dir + "/order.png");
  so.title = "Work-precision";
  render_png(work_figure(runs, so), dir + "/work.png");
  std::printf("wrote state, energy, phase, order, work figures to %s\n", dir.c_str());
  return 0;
}

// render/: a 1600x1000 two-panel state figure with four 100k-point series, rendered and written
// as PNG (target: <= 300 ms on a 2-core machine). The stages are timed separately as well.
#include <benchmark/benchmark.h>

#include <filesystem>

#include "moreau/render/figures.h"
#include "moreau/render/layout.h"
#include "moreau/render/render.h"
#include "synthetic.h"

using namespace moreau::render;

namespace {

const Figure& state_100k() {
  static const Figure f = [] {
    const TimeSeriesData d = synthetic::trajectory(100000);
    FigureOptions o;
    o.width_px = 1600;
    o.height_px = 1000;
    o.title = "Bouncing ball and Coulomb oscillator";
    return state_figure(d, o);
  }();
  return f;
}

void BM_StateFigurePngFile(benchmark::State& state) {
  const Figure& f = state_100k();
  const std::string path = (std::filesystem::temp_directory_path() / "moreau_render_bench.png").string();
  for (auto _ : state) render_png(f, path);
  state.counters["bytes"] = static_cast<double>(std::filesystem::file_size(path));
  std::filesystem::remove(path);
}
BENCHMARK(BM_StateFigurePngFile)->Unit(benchmark::kMillisecond)->MinTime(2.0);

void BM_StateFigureRgba(benchmark::State& state) {
  const Figure& f = state_100k();
  for (auto _ : state) benchmark::DoNotOptimize(render_rgba(f));
}
BENCHMARK(BM_StateFigureRgba)->Unit(benchmark::kMillisecond);

void BM_PngEncode(benchmark::State& state) {
  const Image im = render_rgba(state_100k());
  PngOptions o;
  o.compression_level = static_cast<int>(state.range(0));
  std::size_t bytes = 0;
  for (auto _ : state) bytes = encode_png(im, o).size();
  state.counters["bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_PngEncode)->Arg(1)->Arg(2)->Arg(3)->Arg(6)->Unit(benchmark::kMillisecond);

void BM_Layout(benchmark::State& state) {
  const Figure& f = state_100k();
  for (auto _ : state) benchmark::DoNotOptimize(compute_layout(f));
}
BENCHMARK(BM_Layout)->Unit(benchmark::kMillisecond);

void BM_StateFigureSvg(benchmark::State& state) {
  const Figure& f = state_100k();
  std::size_t bytes = 0;
  for (auto _ : state) bytes = render_svg(f).size();
  state.counters["bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_StateFigureSvg)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();

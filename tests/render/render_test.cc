// render/: the PNG backend (OSMesa, headless) and the SVG backend, checked on the pixels.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <png.h>

#include <cmath>
#include <csetjmp>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include "moreau/render/layout.h"
#include "moreau/render/render.h"

#include "support/scratch_dir.h"
#include "support/xml_chars.h"

using namespace moreau::render;
using ::testing::HasSubstr;

// Under MOREAU_SANITIZE: Mesa keeps a few hundred bytes of per-thread state that LeakSanitizer
// reports at exit. Not ours to free; the suppression is read only when the sanitizer runs.
extern "C" const char* __lsan_default_suppressions() { return "leak:libOSMesa.so\nleak:libLLVM\n"; }

namespace {

// Independent PNG reader (plain libpng), so the encoder is not checked against itself.
struct Decoded {
  png_uint_32 width = 0, height = 0;
  int color_type = -1, bit_depth = 0;
  std::vector<std::uint8_t> rgb;  // 3 bytes per pixel, top-down
};

struct MemReader {
  const std::vector<std::uint8_t>* data;
  std::size_t pos;
};

void mem_read(png_structp png, png_bytep out, png_size_t n) {
  auto* r = static_cast<MemReader*>(png_get_io_ptr(png));
  if (r->pos + n > r->data->size()) png_error(png, "truncated");
  std::copy_n(r->data->data() + r->pos, n, out);
  r->pos += n;
}

bool libpng_decode(const std::vector<std::uint8_t>& bytes, Decoded& out) {
  if (bytes.size() < 8 || png_sig_cmp(bytes.data(), 0, 8)) return false;
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  MemReader reader{&bytes, 0};
  std::vector<png_bytep> rows;
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    return false;
  }
  png_set_read_fn(png, &reader, mem_read);
  png_read_info(png, info);
  out.width = png_get_image_width(png, info);
  out.height = png_get_image_height(png, info);
  out.color_type = png_get_color_type(png, info);
  out.bit_depth = png_get_bit_depth(png, info);
  if (out.color_type != PNG_COLOR_TYPE_RGB || out.bit_depth != 8) {
    png_destroy_read_struct(&png, &info, nullptr);
    return false;
  }
  out.rgb.resize(static_cast<std::size_t>(out.width) * out.height * 3);
  rows.resize(out.height);
  for (png_uint_32 r = 0; r < out.height; ++r) rows[r] = out.rgb.data() + static_cast<std::size_t>(r) * out.width * 3;
  png_read_image(png, rows.data());
  png_read_end(png, nullptr);
  png_destroy_read_struct(&png, &info, nullptr);
  return true;
}

bool close_to(const std::uint8_t* px, Rgb c, int tol) {
  return std::abs(px[0] - c.r) <= tol && std::abs(px[1] - c.g) <= tol && std::abs(px[2] - c.b) <= tol;
}

// Anti-aliased ink of colour c over white: px lies near the white-to-c segment, at least `min_t` of
// the way to c.
bool ink_of(const std::uint8_t* px, Rgb c, double min_t = 0.4) {
  const double d[3] = {255.0 - c.r, 255.0 - c.g, 255.0 - c.b};
  const double p[3] = {255.0 - px[0], 255.0 - px[1], 255.0 - px[2]};
  const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  const double t = (p[0] * d[0] + p[1] * d[1] + p[2] * d[2]) / dd;
  if (t < min_t) return false;
  double off = 0;
  for (int k = 0; k < 3; ++k) off += (p[k] - t * d[k]) * (p[k] - t * d[k]);
  return off < 20.0 * 20.0;
}

bool dark(const std::uint8_t* px) { return px[0] < 110 && px[1] < 110 && px[2] < 110; }

int count_in(const Image& im, const Rect& r, bool (*pred)(const std::uint8_t*)) {
  int n = 0;
  for (int y = std::max(0, static_cast<int>(r.y)); y < std::min(im.height, static_cast<int>(r.bottom())); ++y)
    for (int x = std::max(0, static_cast<int>(r.x)); x < std::min(im.width, static_cast<int>(r.right())); ++x)
      n += pred(im.pixel(x, y)) ? 1 : 0;
  return n;
}

int count_color(const Image& im, Rgb c, int tol) {
  int n = 0;
  for (int y = 0; y < im.height; ++y)
    for (int x = 0; x < im.width; ++x) n += close_to(im.pixel(x, y), c, tol) ? 1 : 0;
  return n;
}

// y = level on x in [0, 1], both axes fixed to [0, 1].
Figure flat_line_figure(double level, int width = 400, int height = 300) {
  Figure f;
  f.width_px = width;
  f.height_px = height;
  f.title = "Flat line";
  Panel p;
  p.x_label = "x";
  p.y_label = "y";
  p.x_axis.min = 0;
  p.x_axis.max = 1;
  p.y_axis.min = 0;
  p.y_axis.max = 1;
  p.legend = false;
  Series s;
  s.label = "level";
  s.x = {0, 1};
  s.y = {level, level};
  p.series.push_back(s);
  f.panels.push_back(p);
  return f;
}

Figure three_series_figure(std::size_t n = 2000) {
  Figure f;
  f.width_px = 640;
  f.height_px = 480;
  f.title = "Three series";
  Panel p;
  p.title = "signals";
  p.x_label = "t";
  p.y_label = "value";
  for (int k = 0; k < 3; ++k) {
    Series s;
    s.label = "signal " + std::to_string(k);
    for (std::size_t i = 0; i < n; ++i) {
      const double t = 10.0 * static_cast<double>(i) / static_cast<double>(n - 1);
      s.x.push_back(t);
      s.y.push_back(std::sin(t + 2.0 * k) + 3.0 * k);
    }
    p.series.push_back(s);
  }
  f.panels.push_back(p);
  return f;
}

}  // namespace

TEST(RenderPng, DecodesWithTheRightSize) {
  const Figure f = flat_line_figure(0.5, 333, 222);
  const std::vector<std::uint8_t> bytes = render_png_bytes(f);
  Decoded d;
  ASSERT_TRUE(libpng_decode(bytes, d));
  EXPECT_EQ(d.width, 333u);
  EXPECT_EQ(d.height, 222u);
  EXPECT_EQ(d.color_type, PNG_COLOR_TYPE_RGB);
  // The library's own decoder agrees with libpng, pixel for pixel.
  const Image im = decode_png(bytes);
  ASSERT_EQ(im.width, 333);
  ASSERT_EQ(im.height, 222);
  for (std::size_t i = 0, j = 0; i < d.rgb.size(); i += 3, j += 4) {
    ASSERT_EQ(d.rgb[i], im.rgba[j]);
    ASSERT_EQ(d.rgb[i + 1], im.rgba[j + 1]);
    ASSERT_EQ(d.rgb[i + 2], im.rgba[j + 2]);
  }
  // And both match the raw render.
  const Image raw = render_rgba(f);
  EXPECT_EQ(raw.rgba, im.rgba);
}

TEST(RenderPng, KnownLineLandsOnTheExpectedRows) {
  for (double level : {0.5, 0.8}) {
    const Figure f = flat_line_figure(level);
    const FigureLayout layout = compute_layout(f);
    const PanelLayout& pl = layout.panels[0];
    const int expected = static_cast<int>(std::floor(pl.y.to_pixel(level)));
    const Image im = render_rgba(f);
    const Rgb c = palette_color(0);
    int columns = 0;
    for (int x = static_cast<int>(pl.plot.x) + 5; x < static_cast<int>(pl.plot.right()) - 5; x += 7) {
      int lo = im.height, hi = -1;
      for (int y = 0; y < im.height; ++y)
        if (ink_of(im.pixel(x, y), c)) {
          lo = std::min(lo, y);
          hi = std::max(hi, y);
        }
      ASSERT_GE(hi, 0) << "no line pixel in column " << x;
      EXPECT_GE(lo, expected - 1) << "column " << x << ", level " << level;
      EXPECT_LE(hi, expected + 1) << "column " << x << ", level " << level;
      ++columns;
    }
    EXPECT_GT(columns, 20);
    // The x mapping too: the line starts at x = 0, the left edge of the plot.
    const int left = static_cast<int>(std::floor(pl.x.to_pixel(0.0)));
    EXPECT_TRUE(ink_of(im.pixel(left + 1, expected), c));
  }
}

TEST(RenderPng, EachSeriesColourIsPresent) {
  const Image im = render_rgba(three_series_figure());
  for (int k = 0; k < 3; ++k) EXPECT_GT(count_color(im, palette_color(k), 12), 300) << "series " << k;
  EXPECT_LT(count_color(im, palette_color(3), 12), 10);  // no fourth series, no fourth colour
}

TEST(RenderPng, TextRegionsAreNotEmpty) {
  const Figure f = three_series_figure();
  const FigureLayout layout = compute_layout(f);
  const Rect plot = layout.panels[0].plot;
  const Image im = render_rgba(f);
  // Figure and panel titles above the plot.
  EXPECT_GT(count_in(im, Rect{plot.x, 0, plot.w, plot.y - 2}, dark), 100);
  // y tick labels left of the plot, x tick labels and axis label below it.
  EXPECT_GT(count_in(im, Rect{0, plot.y, plot.x - 8, plot.h}, dark), 100);
  EXPECT_GT(count_in(im, Rect{plot.x, plot.bottom() + 8, plot.w, im.height - plot.bottom() - 8}, dark), 100);
  // The background is white.
  EXPECT_TRUE(close_to(im.pixel(1, 1), Rgb{255, 255, 255}, 0));
}

TEST(RenderPng, DenseSeriesRendersCleanly) {
  const Image im = render_rgba(three_series_figure(100000));
  EXPECT_GT(count_color(im, palette_color(0), 12), 300);
  EXPECT_GT(count_color(im, palette_color(2), 12), 300);
}

TEST(RenderPng, WidthBeyondOneTileIsSeamless) {
  const Figure f = flat_line_figure(0.5, 2600, 200);
  const FigureLayout layout = compute_layout(f);
  const int expected = static_cast<int>(std::floor(layout.panels[0].y.to_pixel(0.5)));
  const Image im = render_rgba(f);
  ASSERT_EQ(im.width, 2600);
  for (int x = 2030; x < 2070; ++x) {
    bool found = false;
    for (int y = expected - 1; y <= expected + 1; ++y) found |= ink_of(im.pixel(x, y), palette_color(0));
    EXPECT_TRUE(found) << "column " << x;
  }
}

TEST(RenderPng, WritesAFile) {
  const std::filesystem::path path = std::filesystem::path(moreau::test_support::scratch_dir()) / "render_test.png";
  render_png(three_series_figure(), path.string());
  std::ifstream in(path, std::ios::binary);
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), {});
  Decoded d;
  ASSERT_TRUE(libpng_decode(bytes, d));
  EXPECT_EQ(d.width, 640u);
  std::filesystem::remove(path);
  EXPECT_THROW(render_png(three_series_figure(), "/nonexistent-dir/x.png"), std::runtime_error);
}

TEST(RenderPng, InvalidFigureThrowsBeforeDrawing) {
  Figure f = flat_line_figure(0.5);
  f.panels[0].series[0].y = {1, std::nan("")};
  EXPECT_THROW(render_png_bytes(f), FigureError);
  EXPECT_THROW(render_svg(f), FigureError);
}

TEST(RenderPng, ConcurrentRenderingFromTwoThreads) {
  const Figure a = three_series_figure();
  const Figure b = flat_line_figure(0.3);
  const Image ref_a = render_rgba(a), ref_b = render_rgba(b);
  std::vector<Image> out_a(3), out_b(3);
  std::vector<std::vector<std::uint8_t>> png_a(3);
  std::thread ta([&] {
    for (int i = 0; i < 3; ++i) {
      out_a[i] = render_rgba(a);
      png_a[i] = render_png_bytes(a);
    }
  });
  std::thread tb([&] {
    for (int i = 0; i < 3; ++i) out_b[i] = render_rgba(b);
  });
  ta.join();
  tb.join();
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(out_a[i].rgba, ref_a.rgba);
    EXPECT_EQ(out_b[i].rgba, ref_b.rgba);
    EXPECT_EQ(decode_png(png_a[i]).rgba, ref_a.rgba);
  }
}

TEST(RenderSvg, OnePolylinePerSeries) {
  Figure f = three_series_figure();
  Panel second = f.panels[0];
  second.series.resize(1);
  second.title = "second <panel> & more";
  f.panels.push_back(second);
  const std::string svg = render_svg(f);
  std::size_t count = 0;
  for (std::size_t pos = svg.find("<polyline"); pos != std::string::npos; pos = svg.find("<polyline", pos + 1)) ++count;
  EXPECT_EQ(count, 4u);
  EXPECT_EQ(svg.rfind("<?xml", 0), 0u);
  EXPECT_THAT(svg, HasSubstr("width=\"640\" height=\"480\""));
  EXPECT_THAT(svg, HasSubstr(">Three series</text>"));
  EXPECT_THAT(svg, HasSubstr("second &lt;panel&gt; &amp; more"));
  EXPECT_THAT(svg, HasSubstr("clip-path=\"url(#plot0)\""));
  EXPECT_THAT(svg, HasSubstr("stroke=\"#0072b2\""));
  EXPECT_EQ(svg.substr(svg.size() - 7), "</svg>\n");
}

// A figure's title is a scene name a client chose. Control bytes, bytes that are not UTF-8, U+FFFE and
// C1 controls in it once made the SVG invalid XML (no viewer or parser opens it): each becomes U+FFFD,
// and the markup characters stay references.
TEST(RenderSvg, ControlBytesInTextStillGiveXml10) {
  Figure f = three_series_figure(200);
  f.title = std::string("ctl\x01\x1b[2J\x7f|\xc2\x9b|\xef\xbf\xbe|\xff|\xed\xa0\x80|<&>\"|\0|", 30) + "caf\xc3\xa9";
  f.panels[0].title = "panel\x07";
  const std::string svg = render_svg(f);
  EXPECT_EQ(moreau::test_support::xml_1_0_problem(svg), "");
  const std::string r = "\xef\xbf\xbd";  // U+FFFD
  // \xed\xa0\x80 (a surrogate) is three bytes that are not UTF-8: three replacements.
  EXPECT_THAT(svg, HasSubstr(">ctl" + r + r + "[2J" + r + "|" + r + "|" + r + "|" + r + "|" + r + r + r + "|&lt;&amp;&gt;&quot;|" + r +
                             "|caf\xc3\xa9</text>"));
  EXPECT_THAT(svg, HasSubstr(">panel" + r + "</text>"));
}

TEST(RenderSvg, DenseSeriesIsDecimatedAndLogLabelsUseSuperscripts) {
  Figure f = three_series_figure(100000);
  f.panels[0].series.resize(1);
  for (double& y : f.panels[0].series[0].y) y = std::pow(10.0, 3 * y);  // 1e-3 .. 1e3
  f.panels[0].y_axis.scale = Scale::log;
  const std::string svg = render_svg(f);
  EXPECT_LT(svg.size(), 200000u);
  EXPECT_THAT(svg, HasSubstr("10<tspan"));
}

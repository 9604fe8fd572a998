// PNG backend, drawing part: the scene rasterised with OpenGL on an OSMesa (llvmpipe) context.
//
// One offscreen context for the process, created on first use and kept (shader compilation and the
// glyph atlas are paid once), used by one render at a time under a mutex and released after each
// render so any thread can take it next. Drawing goes to a 4x multisampled framebuffer object,
// resolved with a blit and read back; large figures are drawn in tiles to bound memory.
//
// Lines are expanded to triangles on the CPU (quads per segment, round joins where the line turns)
// from series already decimated to a few vertices per pixel column, so multisampling alone gives
// clean anti-aliased lines. Text is FreeType coverage in alpha textures, drawn as blended quads on
// whole pixels.
#define GL_GLEXT_PROTOTYPES 1
#include <GL/osmesa.h>
#include <GL/gl.h>
#include <GL/glext.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <mutex>
#include <numbers>
#include <stdexcept>
#include <unordered_map>

#include "backends.h"
#include "font.h"

namespace moreau::render::detail {
namespace {

constexpr int kTile = 2048;
constexpr int kSamples = 4;
constexpr int kAtlasSize = 1024;
constexpr std::size_t kMaxAtlasPages = 8;

struct Vertex {
  float x, y;
  float u, v;
  std::uint8_t rgba[4];
};

struct AtlasSlot {
  std::size_t page = 0;
  int x = 0, y = 0;
};

class GlContext {
 public:
  static GlContext& instance() {
    static GlContext* ctx = new GlContext();  // kept for the life of the process
    return *ctx;
  }

  std::mutex& mutex() { return mutex_; }

  void make_current() {
    if (!ctx_) {
      ctx_ = OSMesaCreateContextExt(OSMESA_RGBA, 0, 0, 0, nullptr);
      if (!ctx_) throw std::runtime_error("OSMesa: cannot create an offscreen OpenGL context");
    }
    if (!OSMesaMakeCurrent(ctx_, dummy_, GL_UNSIGNED_BYTE, 16, 16))
      throw std::runtime_error("OSMesa: cannot make the offscreen context current");
  }

  void release() { OSMesaMakeCurrent(nullptr, nullptr, 0, 0, 0); }

  // Framebuffers of at least w x h (multisampled for drawing, single-sampled for the resolve).
  void ensure_framebuffers(int w, int h) {
    if (w == fb_w_ && h == fb_h_) return;
    if (fb_w_) {
      glDeleteFramebuffers(2, fbo_);
      glDeleteRenderbuffers(2, rb_);
    }
    glGenFramebuffers(2, fbo_);
    glGenRenderbuffers(2, rb_);
    glBindRenderbuffer(GL_RENDERBUFFER, rb_[0]);
    glRenderbufferStorageMultisample(GL_RENDERBUFFER, kSamples, GL_RGBA8, w, h);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_[0]);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rb_[0]);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw std::runtime_error("OSMesa: multisampled framebuffer incomplete");
    glBindRenderbuffer(GL_RENDERBUFFER, rb_[1]);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, w, h);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_[1]);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rb_[1]);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw std::runtime_error("OSMesa: resolve framebuffer incomplete");
    fb_w_ = w;
    fb_h_ = h;
  }

  GLuint draw_fbo() const { return fbo_[0]; }
  GLuint resolve_fbo() const { return fbo_[1]; }

  // Drops the glyph atlas when it has grown large (between renders only).
  void trim_atlas() {
    if (pages_.size() < kMaxAtlasPages) return;
    glDeleteTextures(static_cast<GLsizei>(pages_.size()), pages_.data());
    pages_.clear();
    slots_.clear();
    shelf_x_ = shelf_y_ = shelf_h_ = 0;
  }

  AtlasSlot slot(const Glyph* g) {
    auto it = slots_.find(g);
    if (it != slots_.end()) return it->second;
    const int w = g->width + 1, h = g->height + 1;
    if (pages_.empty() || shelf_x_ + w > kAtlasSize) {
      shelf_x_ = 0;
      shelf_y_ += shelf_h_;
      shelf_h_ = 0;
    }
    if (pages_.empty() || shelf_y_ + h > kAtlasSize) new_page();
    AtlasSlot s{pages_.size() - 1, shelf_x_, shelf_y_};
    glBindTexture(GL_TEXTURE_2D, pages_.back());
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexSubImage2D(GL_TEXTURE_2D, 0, s.x, s.y, g->width, g->height, GL_ALPHA, GL_UNSIGNED_BYTE, g->coverage.data());
    shelf_x_ += w;
    shelf_h_ = std::max(shelf_h_, h);
    slots_.emplace(g, s);
    return s;
  }

  GLuint page(std::size_t i) const { return pages_[i]; }

 private:
  void new_page() {
    GLuint tex = 0;
    glGenTextures(1, &tex);
    glBindTexture(GL_TEXTURE_2D, tex);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    const std::vector<std::uint8_t> zeros(static_cast<std::size_t>(kAtlasSize) * kAtlasSize, 0);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_ALPHA, kAtlasSize, kAtlasSize, 0, GL_ALPHA, GL_UNSIGNED_BYTE, zeros.data());
    pages_.push_back(tex);
    shelf_x_ = shelf_y_ = shelf_h_ = 0;
  }

  std::mutex mutex_;
  OSMesaContext ctx_ = nullptr;
  std::uint8_t dummy_[16 * 16 * 4] = {};
  GLuint fbo_[2] = {0, 0}, rb_[2] = {0, 0};
  int fb_w_ = 0, fb_h_ = 0;
  std::vector<GLuint> pages_;
  std::unordered_map<const Glyph*, AtlasSlot> slots_;
  int shelf_x_ = 0, shelf_y_ = 0, shelf_h_ = 0;
};

// Liang-Barsky: clips segment a-b to r; false if nothing remains.
bool clip_segment(Point& a, Point& b, const Rect& r) {
  double t0 = 0, t1 = 1;
  const double dx = b.x - a.x, dy = b.y - a.y;
  const double p[4] = {-dx, dx, -dy, dy};
  const double q[4] = {a.x - r.x, r.right() - a.x, a.y - r.y, r.bottom() - a.y};
  for (int i = 0; i < 4; ++i) {
    if (p[i] == 0) {
      if (q[i] < 0) return false;
      continue;
    }
    const double t = q[i] / p[i];
    if (p[i] < 0)
      t0 = std::max(t0, t);
    else
      t1 = std::min(t1, t);
    if (t0 > t1) return false;
  }
  const Point a0 = a;
  a = {a0.x + t0 * dx, a0.y + t0 * dy};
  b = {a0.x + t1 * dx, a0.y + t1 * dy};
  return true;
}

class Batcher {
 public:
  Batcher(GlContext& gl, int tile_x, int tile_y, int tile_w, int tile_h) : gl_(gl), tx_(tile_x), ty_(tile_y), tw_(tile_w), th_(tile_h) {
    verts_.reserve(1 << 16);
  }

  void draw(const Item& item) {
    std::visit([this](const auto& it) { this->add(it); }, item);
  }

  void flush() {
    if (verts_.empty()) return;
    if (clip_) {
      const int x0 = static_cast<int>(std::floor(clip_->x)) - tx_;
      const int x1 = static_cast<int>(std::ceil(clip_->right())) - tx_;
      const int y0 = (ty_ + th_) - static_cast<int>(std::ceil(clip_->bottom()));
      const int y1 = (ty_ + th_) - static_cast<int>(std::floor(clip_->y));
      glEnable(GL_SCISSOR_TEST);
      glScissor(x0, y0, std::max(0, x1 - x0), std::max(0, y1 - y0));
    } else {
      glDisable(GL_SCISSOR_TEST);
    }
    const GLsizei stride = sizeof(Vertex);
    glVertexPointer(2, GL_FLOAT, stride, &verts_[0].x);
    glColorPointer(4, GL_UNSIGNED_BYTE, stride, &verts_[0].rgba[0]);
    if (page_) {
      glEnable(GL_TEXTURE_2D);
      glBindTexture(GL_TEXTURE_2D, gl_.page(*page_));
      glEnableClientState(GL_TEXTURE_COORD_ARRAY);
      glTexCoordPointer(2, GL_FLOAT, stride, &verts_[0].u);
    } else {
      glDisable(GL_TEXTURE_2D);
      glDisableClientState(GL_TEXTURE_COORD_ARRAY);
    }
    glDrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(verts_.size()));
    verts_.clear();
  }

 private:
  static bool same(const std::optional<Rect>& a, const std::optional<Rect>& b) {
    if (a.has_value() != b.has_value()) return false;
    return !a || (a->x == b->x && a->y == b->y && a->w == b->w && a->h == b->h);
  }

  void state(std::optional<std::size_t> page, const std::optional<Rect>& clip) {
    if (page != page_ || !same(clip, clip_)) {
      flush();
      page_ = page;
      clip_ = clip;
    }
  }

  bool visible(const Rect& r) const { return r.right() >= tx_ && r.x <= tx_ + tw_ && r.bottom() >= ty_ && r.y <= ty_ + th_; }

  void vertex(double x, double y, Rgba c, float u = 0, float v = 0) {
    verts_.push_back({static_cast<float>(x), static_cast<float>(y), u, v, {c.r, c.g, c.b, c.a}});
  }

  void quad(Point a, Point b, Point c, Point d, Rgba col) {  // a-b-c-d around
    vertex(a.x, a.y, col);
    vertex(b.x, b.y, col);
    vertex(c.x, c.y, col);
    vertex(a.x, a.y, col);
    vertex(c.x, c.y, col);
    vertex(d.x, d.y, col);
  }

  void disc(Point c, double r, Rgba col) {
    const int n = std::clamp(static_cast<int>(std::ceil(r * 3)), 8, 40);
    double px = c.x + r, py = c.y;
    for (int i = 1; i <= n; ++i) {
      const double a = 2 * std::numbers::pi * i / n;
      const double qx = c.x + r * std::cos(a), qy = c.y + r * std::sin(a);
      vertex(c.x, c.y, col);
      vertex(px, py, col);
      vertex(qx, qy, col);
      px = qx;
      py = qy;
    }
  }

  void add(const FillRect& f) {
    if (!visible(f.rect)) return;
    state(std::nullopt, f.clip);
    const Rect& r = f.rect;
    quad({r.x, r.y}, {r.right(), r.y}, {r.right(), r.bottom()}, {r.x, r.bottom()}, f.color);
  }

  void add(const Dots& d) {
    state(std::nullopt, d.clip);
    const Rect view{tx_ - d.radius, ty_ - d.radius, tw_ + 2 * d.radius, th_ + 2 * d.radius};
    for (const Point& c : d.centers)
      if (view.contains(c.x, c.y) &&
          (!d.clip ||
           Rect{d.clip->x - d.radius, d.clip->y - d.radius, d.clip->w + 2 * d.radius, d.clip->h + 2 * d.radius}.contains(c.x, c.y)))
        disc(c, d.radius, d.color);
  }

  void add(const Stroke& s) {
    state(std::nullopt, s.clip);
    const double hw = s.width / 2;
    // Segments are clipped to the visible area (tile and clip rectangle) grown by the line width.
    Rect bounds{static_cast<double>(tx_), static_cast<double>(ty_), static_cast<double>(tw_), static_cast<double>(th_)};
    if (s.clip) {
      const double x0 = std::max(bounds.x, s.clip->x), y0 = std::max(bounds.y, s.clip->y);
      const double x1 = std::min(bounds.right(), s.clip->right()), y1 = std::min(bounds.bottom(), s.clip->bottom());
      if (x1 < x0 || y1 < y0) return;
      bounds = {x0, y0, x1 - x0, y1 - y0};
    }
    bounds = {bounds.x - 2 * s.width, bounds.y - 2 * s.width, bounds.w + 4 * s.width, bounds.h + 4 * s.width};

    if (s.dashed) {
      const double on = std::max(4.0, 4 * s.width), off = std::max(3.0, 3 * s.width);
      for (std::size_t i = 1; i < s.points.size(); ++i) {
        Point a = s.points[i - 1], b = s.points[i];
        const double len = std::hypot(b.x - a.x, b.y - a.y);
        if (len <= 0) continue;
        const double ux = (b.x - a.x) / len, uy = (b.y - a.y) / len;
        for (double t = 0; t < len; t += on + off) {
          Point p{a.x + ux * t, a.y + uy * t};
          const double e = std::min(len, t + on);
          Point q{a.x + ux * e, a.y + uy * e};
          if (clip_segment(p, q, bounds)) segment(p, q, hw, s.color);
        }
      }
      return;
    }

    // Drop repeated points so every segment has a direction.
    std::vector<Point> pts;
    pts.reserve(s.points.size());
    for (const Point& p : s.points)
      if (pts.empty() || std::abs(p.x - pts.back().x) > 1e-7 || std::abs(p.y - pts.back().y) > 1e-7) pts.push_back(p);
    if (pts.size() == 1) {
      if (bounds.contains(pts[0].x, pts[0].y)) disc(pts[0], hw, s.color);
      return;
    }
    for (std::size_t i = 1; i < pts.size(); ++i) {
      Point a = pts[i - 1], b = pts[i];
      if (!clip_segment(a, b, bounds)) continue;
      segment(a, b, hw, s.color);
      // Round join at b where the line turns by more than ~10 degrees.
      if (i + 1 < pts.size() && bounds.contains(pts[i].x, pts[i].y)) {
        const Point& p0 = pts[i - 1];
        const Point& p1 = pts[i];
        const Point& p2 = pts[i + 1];
        const double ax = p1.x - p0.x, ay = p1.y - p0.y, bx = p2.x - p1.x, by = p2.y - p1.y;
        const double cross = ax * by - ay * bx, dot = ax * bx + ay * by;
        if (dot < 0 || std::abs(cross) > 0.17 * std::hypot(ax, ay) * std::hypot(bx, by)) disc(p1, hw, s.color);
      }
    }
  }

  void segment(Point a, Point b, double hw, Rgba c) {
    const double dx = b.x - a.x, dy = b.y - a.y;
    const double len = std::hypot(dx, dy);
    if (len < 1e-9) return;
    const double nx = -dy / len * hw, ny = dx / len * hw;
    quad({a.x + nx, a.y + ny}, {b.x + nx, b.y + ny}, {b.x - nx, b.y - ny}, {a.x - nx, a.y - ny}, c);
  }

  void add(const Text& t) {
    const ShapedText shaped = shape_text(t.text, t.size_px, t.bold);
    const int sup_px = superscript_px(t.size_px);
    const ShapedText sup = t.superscript.empty() ? ShapedText{} : shape_text(t.superscript, sup_px, t.bold);
    const int width = shaped.width + sup.width;
    double offset = 0;
    if (t.align == Text::Align::center)
      offset = std::round(width / 2.0);
    else if (t.align == Text::Align::right)
      offset = width;
    glyphs(t, shaped, -offset, 0);
    if (!t.superscript.empty()) glyphs(t, sup, shaped.width - offset, -superscript_rise(t.size_px));
  }

  // Glyph quads of a shaped run starting at `along` pixels from the anchor, `down` pixels below the
  // baseline (in text coordinates; rotated for vertical text).
  void glyphs(const Text& t, const ShapedText& run, double along, double down) {
    const double ax = std::round(t.x), ay = std::round(t.y);
    const float inv = 1.0f / kAtlasSize;
    for (const PlacedGlyph& pg : run.glyphs) {
      const Glyph& g = *pg.glyph;
      if (g.width == 0 || g.height == 0) continue;
      const AtlasSlot slot = gl_.slot(pg.glyph);
      state(slot.page, std::nullopt);
      const double l0 = along + pg.pen_x + g.left, l1 = l0 + g.width;
      const double d0 = down - g.top, d1 = d0 + g.height;
      const float u0 = slot.x * inv, u1 = (slot.x + g.width) * inv;
      const float v0 = slot.y * inv, v1 = (slot.y + g.height) * inv;
      auto at = [&](double l, double d) { return t.vertical ? Point{ax + d, ay - l} : Point{ax + l, ay + d}; };
      const Point p00 = at(l0, d0), p10 = at(l1, d0), p11 = at(l1, d1), p01 = at(l0, d1);
      vertex(p00.x, p00.y, t.color, u0, v0);
      vertex(p10.x, p10.y, t.color, u1, v0);
      vertex(p11.x, p11.y, t.color, u1, v1);
      vertex(p00.x, p00.y, t.color, u0, v0);
      vertex(p11.x, p11.y, t.color, u1, v1);
      vertex(p01.x, p01.y, t.color, u0, v1);
    }
  }

  GlContext& gl_;
  int tx_, ty_, tw_, th_;
  std::vector<Vertex> verts_;
  std::optional<std::size_t> page_;
  std::optional<Rect> clip_;
};

}  // namespace

Image rasterize_with_opengl(const Scene& scene) {
  Image image;
  image.width = scene.width;
  image.height = scene.height;
  image.rgba.resize(static_cast<std::size_t>(scene.width) * scene.height * 4);

  GlContext& gl = GlContext::instance();
  std::lock_guard lock(gl.mutex());
  gl.make_current();
  struct Release {
    GlContext& gl;
    ~Release() { gl.release(); }
  } release{gl};

  gl.trim_atlas();
  const int fw = std::min(scene.width, kTile), fh = std::min(scene.height, kTile);
  gl.ensure_framebuffers(fw, fh);

  glDisable(GL_DEPTH_TEST);
  glDisable(GL_CULL_FACE);
  glDisable(GL_LIGHTING);
  glEnable(GL_BLEND);
  glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
  glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_MODULATE);
  glEnableClientState(GL_VERTEX_ARRAY);
  glEnableClientState(GL_COLOR_ARRAY);
  glMatrixMode(GL_MODELVIEW);
  glLoadIdentity();
  glClearColor(1, 1, 1, 1);

  std::vector<std::uint8_t> tile(static_cast<std::size_t>(fw) * fh * 4);
  for (int ty = 0; ty < scene.height; ty += kTile) {
    for (int tx = 0; tx < scene.width; tx += kTile) {
      const int tw = std::min(kTile, scene.width - tx), th = std::min(kTile, scene.height - ty);
      glBindFramebuffer(GL_FRAMEBUFFER, gl.draw_fbo());
      glViewport(0, 0, tw, th);
      glDisable(GL_SCISSOR_TEST);
      glClear(GL_COLOR_BUFFER_BIT);
      glMatrixMode(GL_PROJECTION);
      glLoadIdentity();
      glOrtho(tx, tx + tw, ty + th, ty, -1, 1);

      Batcher batch(gl, tx, ty, tw, th);
      for (const Item& item : scene.items) batch.draw(item);
      batch.flush();

      glDisable(GL_SCISSOR_TEST);
      glBindFramebuffer(GL_READ_FRAMEBUFFER, gl.draw_fbo());
      glBindFramebuffer(GL_DRAW_FRAMEBUFFER, gl.resolve_fbo());
      glBlitFramebuffer(0, 0, tw, th, 0, 0, tw, th, GL_COLOR_BUFFER_BIT, GL_NEAREST);
      glBindFramebuffer(GL_READ_FRAMEBUFFER, gl.resolve_fbo());
      glPixelStorei(GL_PACK_ALIGNMENT, 1);
      glReadPixels(0, 0, tw, th, GL_RGBA, GL_UNSIGNED_BYTE, tile.data());

      // OpenGL rows run bottom-up: flip into the top-down image.
      for (int r = 0; r < th; ++r) {
        const std::uint8_t* src = tile.data() + static_cast<std::size_t>(th - 1 - r) * tw * 4;
        std::uint8_t* dst = image.rgba.data() + (static_cast<std::size_t>(ty + r) * scene.width + tx) * 4;
        std::memcpy(dst, src, static_cast<std::size_t>(tw) * 4);
      }
    }
  }
  const GLenum err = glGetError();
  if (err != GL_NO_ERROR) throw std::runtime_error("OpenGL error " + std::to_string(err) + " while rendering");
  for (std::size_t i = 3; i < image.rgba.size(); i += 4) image.rgba[i] = 255;
  return image;
}

}  // namespace moreau::render::detail

// The entry point the loader (gl_loader.cc) looks up: this file is built as its own shared module, so
// that OSMesa and LLVM are loaded only by a process that draws a PNG.
extern "C" __attribute__((visibility("default"))) int moreau_render_gl_rasterize(const moreau::render::detail::Scene* scene,
                                                                                 moreau::render::Image* image, std::string* error) {
  return moreau::render::detail::module_entry(error, [&] { *image = moreau::render::detail::rasterize_with_opengl(*scene); });
}

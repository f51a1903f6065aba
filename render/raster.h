// Draws a scene's distance meshes into an id + depth framebuffer and reads it back as a Frame.
// Everything here needs the thread's current GL context (see GlContext).
#pragma once

#include <cstdint>
#include <map>
#include <memory>

#include "absl/status/statusor.h"
#include "render/frame.h"
#include "render/geometry.h"
#include "render/site.h"

namespace gvd {

// A framebuffer object with an R32UI id attachment (0 = no site, else site index + 1) and a
// 32-bit float depth attachment, at one resolution. Rendering always targets an FBO, never a
// window surface. Not thread-safe; the context that made it must be current.
class RenderTarget {
 public:
  static absl::StatusOr<std::unique_ptr<RenderTarget>> Create(uint32_t width, uint32_t height);
  ~RenderTarget();
  RenderTarget(const RenderTarget&) = delete;
  RenderTarget& operator=(const RenderTarget&) = delete;

  uint32_t width() const { return width_; }
  uint32_t height() const { return height_; }
  unsigned framebuffer() const { return fbo_; }

 private:
  RenderTarget(uint32_t width, uint32_t height) : width_(width), height_(height) {}
  uint32_t width_, height_;
  unsigned fbo_ = 0, ids_ = 0, depth_ = 0;
};

struct RenderStats {
  uint32_t cone_segments = 0;  // triangles in the largest point cone of this render
  uint64_t sites_drawn = 0;    // sites nearest to some pixel centre
  double fill_ratio = 0;       // total area of the drawn meshes / area of the window
  uint32_t tile_px = 0;        // tile side of the coverage pass
  double coverage_seconds = 0; // spatial index and coverage radii
  double draw_seconds = 0;     // until the GPU finished drawing
  double readback_seconds = 0;
  PixelRect window;            // bounds the pixels redrawn and read back
  size_t windows = 0;          // separate windows redrawn
  uint64_t pixels = 0;         // pixels redrawn and read back
  bool full = false;           // a render from scratch
};

// A point site's distance cone to draw: it must cover every pixel centre within `radius`.
struct ConeDraw {
  Vec2 site;
  double radius = 0;
  uint32_t slot = 0;
};

// Compiled shaders and mesh buffers. Not thread-safe; use on the context's thread.
class Rasterizer {
 public:
  static absl::StatusOr<std::unique_ptr<Rasterizer>> Create();
  ~Rasterizer();
  Rasterizer(const Rasterizer&) = delete;
  Rasterizer& operator=(const Rasterizer&) = delete;

  // The triangles and the extent (how far from the site the fan reaches, >= radius) of the
  // cone drawn for a radius: its fan has within-eps error up to the radius.
  struct ConeShape {
    uint32_t segments;
    double overestimate;  // k of the fan
    double extent;
  };
  ConeShape Shape(const Grid& grid, double radius, double eps) const;

  // Draws the cones into `target` inside `scissor` (clearing it first when `clear`), with
  // depth = distance / depth_scale. CONTRACT: every cone's extent <= depth_scale.
  absl::Status Draw(const Grid& grid, double eps, double depth_scale, PixelRect scissor,
                    bool clear, const std::vector<ConeDraw>& cones, RenderTarget& target);

  // Reads `rect` of the target: ids, and distances (depth * depth_scale), row-major.
  absl::Status ReadBack(RenderTarget& target, PixelRect rect, double depth_scale,
                        std::vector<uint32_t>* ids, std::vector<float>* distances);

  // A whole render from scratch, for tests and benchmarks: the same path as a scene's first
  // render (SceneRaster).
  absl::StatusOr<std::shared_ptr<const Frame>> Render(const Grid& grid, double eps,
                                                      uint64_t version, const SiteTable& sites,
                                                      RenderStats* stats = nullptr);

 private:
  Rasterizer() = default;
  // The vertex buffer of the unit cone with `segments` triangles, made on first use.
  unsigned ConeBuffer(uint32_t segments);

  unsigned program_ = 0, vao_ = 0, instances_ = 0;
  int u_scale_ = -1, u_inv_depth_ = -1;
  std::map<uint32_t, unsigned> cones_;  // segments -> vertex buffer
};

}  // namespace gvd

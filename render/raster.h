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

// How distance functions are drawn. kMesh: the paper's bounded-error triangle fans (error at
// most eps, interpolated by the rasterizer). kExact: one quad per site whose fragments
// compute the distance analytically and write it as depth (no meshing error; two triangles
// per site, but no early depth test).
enum class RenderMode { kMesh, kExact };

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

  // What is drawn for a site that must cover `radius`: a fan of `segments` triangles with
  // error within eps up to the radius (kMesh), or a quad (kExact, segments = 2). `extent`
  // bounds the distances it writes and how far from the site it reaches; `scale` sizes it.
  struct ConeShape {
    uint32_t segments;
    double overestimate;  // k of the fan; 1 for quads
    double extent;
    double scale;
  };
  ConeShape Shape(const Grid& grid, double radius, double eps, RenderMode mode) const;

  // Draws the sites' distance functions into `target` inside `scissor` (clearing it first
  // when `clear`), with depth = distance / depth_scale.
  // CONTRACT: every shape's extent <= depth_scale.
  absl::Status Draw(const Grid& grid, double eps, RenderMode mode, double depth_scale,
                    PixelRect scissor, bool clear, const std::vector<ConeDraw>& cones,
                    RenderTarget& target);

  // Reads `rect` of the target: ids, and distances (depth * depth_scale), row-major.
  absl::Status ReadBack(RenderTarget& target, PixelRect rect, double depth_scale,
                        std::vector<uint32_t>* ids, std::vector<float>* distances);

  // A whole render from scratch, for tests and benchmarks: the same path as a scene's first
  // render (SceneRaster).
  absl::StatusOr<std::shared_ptr<const Frame>> Render(const Grid& grid, double eps,
                                                      uint64_t version, const SiteTable& sites,
                                                      RenderStats* stats = nullptr,
                                                      RenderMode mode = RenderMode::kMesh);

 private:
  Rasterizer() = default;
  // The vertex buffer of the unit cone with `segments` triangles, made on first use.
  unsigned ConeBuffer(uint32_t segments);

  struct Program {
    unsigned id = 0;
    int u_scale = -1, u_inv_depth = -1, u_pixel = -1, u_inv_pixel = -1;
  };
  static absl::StatusOr<Program> Link(const char* vertex, const char* fragment);

  Program mesh_, exact_;
  unsigned vao_ = 0, instances_ = 0, quad_ = 0;
  std::map<uint32_t, unsigned> cones_;  // segments -> vertex buffer
};

}  // namespace gvd

// Draws a scene's distance meshes into an id + depth framebuffer and reads it back as a Frame.
// Everything here needs the thread's current GL context (see GlContext).
#pragma once

#include <cstdint>
#include <map>
#include <memory>

#include "absl/status/statusor.h"
#include "render/scene/frame.h"
#include "render/gl/context.h"
#include "render/gl/render_stats.h"
#include "render/scene/settings.h"
#include "render/plan/coverage.h"
#include "render/kernel/exact2.h"
#include "render/kernel/grid2.h"
#include "render/kernel/site2.h"

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

// What drawing one site with a given radius amounts to.
struct SiteShape {
  double extent = 0;        // no fragment lies farther than this from the geometry
  double pad = 0;           // added to a radius for rounding before it is drawn
  double max_value = 0;     // no value written exceeds this (m * extent + a)
  double overestimate = 1;  // k of its fans (1 when none)
  uint32_t segments = 0;    // triangles in each of its fans (0 when none)
  double area = 0;          // the area its pieces cover within the clip
  bool per_fragment = false;  // drawn as a quad evaluated per fragment
  // A bound on height - value over what is drawn: m * eps for fans with enough triangles;
  // m * (k - 1) * extent for a fan that would need more than kMaxConeSegments (a site far
  // from a small window); 0 per fragment.
  double excess = 0;
};

// The fixed parameters of one scene's draws.
struct DrawParams {
  double eps = 0;
  RenderMode mode = RenderMode::kMesh;
  Diagram diagram = Diagram::kNearest;
  double depth_scale = 1;  // depth = value / depth_scale
};

// What a frame's ErrorModel needs to know of the sites drawn into it: the largest weight,
// fan overestimate and excess, Bezier tolerance, coordinate magnitude, and whether presence
// is limited. Reset before a render from scratch; later draws only widen it.
class ErrorTally {
 public:
  void Reset() { *this = ErrorTally(); }
  // A site that is live in the frame (drawn or not).
  void Live(const Site& site);
  // A site drawn with `shape` on `grid`.
  void Drawn(const Grid& grid, const Site& site, const SiteShape& shape);
  ErrorModel Model(const Grid& grid, const DrawParams& params) const;

 private:
  double overestimate_ = 1;
  double max_weight_ = 1;
  double curve_slack_ = 0;
  double coordinate_scale_ = 0;  // relative to the window's min corner
  double excess_ = 0;            // beyond eps * weight, from fans with capped triangle counts
  bool limited_presence_ = false;
};

// Compiled shaders and mesh buffers. Not thread-safe; use on the context's thread.
class Rasterizer {
 public:
  // For the context current on this thread, made on `device`.
  static absl::StatusOr<std::unique_ptr<Rasterizer>> Create(const DeviceInfo& device);
  ~Rasterizer();
  Rasterizer(const Rasterizer&) = delete;
  Rasterizer& operator=(const Rasterizer&) = delete;

  // Whether the context renders on Mesa's software rasterizer (llvmpipe), where a compute
  // pass over candidate lists beats drawing meshes for every site kind (tests/bench/README.md).
  bool software() const { return software_; }

  // Whether Compute scans the lists in native code on the CPU pool rather than in the compute
  // shader: by default on a software device, where llvmpipe would run the shader on the
  // render thread alone (and with an SIMD width the native loop matches). Tests set it to
  // check the shader there.
  bool native_scan() const { return native_scan_; }
  void set_native_scan(bool native) { native_scan_ = native; }

  // How a site that must cover `draw.radius` within `draw.clip` is drawn.
  SiteShape Shape(const Grid& grid, const DrawParams& params, const Site& site,
                  const SiteDraw& draw) const;

  // Draws the sites' distance functions into `target` inside `scissor` (clearing it first
  // when `clear`). The grid's pixel (0, 0) is the target's pixel (x0, y0); the scissor is in
  // grid pixels. CONTRACT: every shape's max_value <= params.depth_scale; the grid, placed
  // at (x0, y0), fits in the target.
  absl::Status Draw(const Grid& grid, const DrawParams& params, PixelRect scissor, bool clear,
                    const SlotTable& sites, const std::vector<SiteDraw>& draws,
                    RenderTarget& target, uint32_t x0 = 0, uint32_t y0 = 0);

  // The side of the tiles whose candidate lists Compute takes.
  static constexpr uint32_t kComputeTile = 8;

  // Candidate lists for Compute, by tile of kComputeTile pixels, row-major. Tile t's plain
  // points (Site::plain) are points[offsets[3t] .. offsets[3t + 3]); the sites it scans
  // whole (polygons restricted to a side whose boundary comes near the tile: the even-odd
  // test needs every edge) are
  // draws[sites[k]] for k in [offsets[3t + 1], offsets[3t + 4]); of the other sites it
  // scans single segments, segments[k] for k in [offsets[3t + 2], offsets[3t + 5]), those
  // that can hold their site's nearest point where it can be best there
  // (TileCover::NeededSegments), a site's next to each other.
  struct Point {  // nearest.comp's Point, std430
    float x, y;   // relative to the window's min corner
    uint32_t id;  // slot + 1
    uint32_t unused = 0;
  };
  struct Segment {   // nearest.comp's uvec2
    uint32_t site;   // draws[site]
    uint32_t index;  // its segment in ForEachSegment order
  };
  struct TileLists {
    std::vector<uint32_t> offsets;  // 3 (tiles + 1) entries
    std::vector<Point> points;
    std::vector<uint32_t> sites;
    std::vector<Segment> segments;
  };

  // A full render of a kNearest diagram into `target` (the grid at its pixel (0, 0)) by a
  // compute shader over per-tile candidate lists, no mesh drawn (on a software device, the
  // same loop in native code on the CPU pool: see native_scan). Each pixel centre gets the
  // least value among its tile's candidates present there (ties to the lower slot), computed
  // as a per-fragment site's, so the lists must hold every site that can be best at some
  // pixel centre of the tile (TileCover), and each draw's radius must reach all of them.
  // Fills `ids` and `distances` as ReadBack would, and leaves the target holding the diagram
  // as Draw would have (depths at params.depth_scale), for later draws over it. CONTRACT:
  // params.diagram is kNearest; every site's value is below params.depth_scale. Returns
  // RESOURCE_EXHAUSTED, having changed nothing, when a buffer would exceed the GL's
  // GL_MAX_SHADER_STORAGE_BLOCK_SIZE (llvmpipe's is 128 MiB: 32M pixels); Draw then serves.
  absl::Status Compute(const Grid& grid, const DrawParams& params, const SlotTable& sites,
                       const std::vector<SiteDraw>& draws, const TileLists& lists,
                       RenderTarget& target, std::vector<uint32_t>* ids,
                       std::vector<float>* distances);

  // Reads `rect` of the target: ids, and distances (depth * depth_scale), row-major.
  absl::Status ReadBack(RenderTarget& target, PixelRect rect, double depth_scale,
                        std::vector<uint32_t>* ids, std::vector<float>* distances);

 private:
  Rasterizer() = default;
  // Writes the computed ids and values in the storage buffers at bindings 4 and 5 into the
  // target's id and depth buffers (Compute's last step).
  absl::Status Resolve(const Grid& grid, const DrawParams& params, RenderTarget& target);
  // The vertex buffer of the unit cone with `segments` triangles, two turns of it, made on
  // first use.
  unsigned ConeBuffer(uint32_t segments);

  struct Program {
    unsigned id = 0;
    int u_scale = -1, u_inv_depth = -1, u_pixel = -1, u_margin = -1, u_origin = -1;
  };
  static absl::StatusOr<Program> Link(const char* vertex, const char* fragment);

  Program cone_, tent_, exact_, exact_point_, resolve_;
  unsigned nearest_ = 0;  // the compute program (nearest.comp)
  unsigned vao_ = 0, instances_ = 0, quad_ = 0, tent_mesh_ = 0, segments_ = 0, indirect_ = 0;
  // Compute's inputs and outputs: sites, tile offsets, candidate sites, ids, values, points,
  // candidate segments.
  unsigned compute_buffers_[7] = {};
  int64_t max_storage_block_ = 0;  // GL_MAX_SHADER_STORAGE_BLOCK_SIZE, bytes
  bool software_ = false;
  bool native_scan_ = false;
  std::map<uint32_t, unsigned> cones_;  // segments -> vertex buffer
};

}  // namespace gvd

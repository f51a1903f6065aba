// Draws a scene's distance meshes into an id + depth framebuffer and reads it back as a Frame.
// Everything here needs the thread's current GL context (see GlContext).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "render/gl/context.h"
#include "render/gl/objects.h"
#include "render/scene/render_stats.h"
#include "render/kernel/grid2.h"
#include "render/plan/coverage.h"
#include "render/plan/site_shape.h"
#include "render/plan/tile_lists.h"
#include "render/scene/slot_table.h"

namespace gvd {

// A framebuffer object with an R32UI id attachment (0 = no site, else site index + 1) and a
// 32-bit float depth attachment, at one resolution. Rendering always targets an FBO, never a
// window surface. Not thread-safe; the context that made it must be current.
class RenderTarget {
 public:
  static absl::StatusOr<std::unique_ptr<RenderTarget>> Create(uint32_t width, uint32_t height);

  uint32_t width() const { return width_; }
  uint32_t height() const { return height_; }
  unsigned framebuffer() const { return fbo_.id(); }

 private:
  RenderTarget(uint32_t width, uint32_t height) : width_(width), height_(height) {}
  uint32_t width_, height_;
  gl::Framebuffer fbo_;
  gl::Renderbuffer ids_, depth_;
};

// Compiled shaders and mesh buffers. Not thread-safe; use on the context's thread.
class Rasterizer {
 public:
  // For the context current on this thread, made on `device`.
  static absl::StatusOr<std::unique_ptr<Rasterizer>> Create(const DeviceInfo& device);
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

  // The calling thread's turn at GL (GlTurn), which Compute gives up during its native scan
  // and takes back after it, and a full render during its planning (SceneRaster); null (the
  // default): none to give up. Must outlive its use.
  void set_gl_turn(GlTurn* turn) { gl_turn_ = turn; }
  GlTurn* gl_turn() const { return gl_turn_; }
  // A test hook, called by a full render once its planning begins, with the turn given up:
  // RenderLoop's held scene (its kHoldRendersVariable) waits there. Null: none.
  void set_planning_hook(std::function<void()> hook) { planning_hook_ = std::move(hook); }
  void RunPlanningHook() const {
    if (planning_hook_) planning_hook_();
  }

  // Draws the sites' distance functions (each as ShapeOf says) into `target` inside `scissor` (clearing it first
  // when `clear`). The grid's pixel (0, 0) is the target's pixel (x0, y0); the scissor is in
  // grid pixels. CONTRACT: every shape's max_value <= params.depth_scale; the grid, placed
  // at (x0, y0), fits in the target.
  absl::Status Draw(const Grid& grid, const DrawParams& params, PixelRect scissor, bool clear,
                    const SlotTable& sites, const std::vector<SiteDraw>& draws,
                    RenderTarget& target, uint32_t x0 = 0, uint32_t y0 = 0);

  // A full render of a kNearest diagram into `target` (the grid at its pixel (0, 0)) by a
  // compute shader over per-tile candidate lists (render/plan/tile_lists.h), no mesh drawn (on
  // a software device, the same loop in native code on the CPU pool, render/plan/scan.h: see
  // native_scan). Each pixel centre gets the
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

  // A linked program and the locations of the uniforms the drawing programs share.
  struct Program {
    gl::Program program;
    int u_scale = -1, u_inv_depth = -1, u_pixel = -1, u_margin = -1, u_origin = -1;
    unsigned id() const { return program.id(); }
  };
  static absl::StatusOr<Program> Link(const char* vertex, const char* fragment);

  Program cone_, tent_, exact_, exact_point_, resolve_;
  gl::Program nearest_;  // the compute program (nearest.comp)
  gl::VertexArray vao_;
  gl::Buffer instances_, quad_, tent_mesh_, segments_, indirect_;
  // Compute's inputs and outputs: sites, tile offsets, candidate sites, ids, values, points,
  // candidate segments.
  std::array<gl::Buffer, 7> compute_buffers_;
  int64_t max_storage_block_ = 0;  // GL_MAX_SHADER_STORAGE_BLOCK_SIZE, bytes
  bool software_ = false;
  bool native_scan_ = false;
  GlTurn* gl_turn_ = nullptr;
  std::function<void()> planning_hook_;
  std::map<uint32_t, gl::Buffer> cones_;  // segments -> vertex buffer
};

}  // namespace gvd

#include "render/gl/rasterizer.h"

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <string>
#include <tuple>
#include <vector>

#include <glm/gtc/type_ptr.hpp>
#include <glm/vec4.hpp>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "render/gl/program.h"
#include "render/gl/shaders.h"
#include "render/kernel/exact2.h"
#include "render/plan/distance_mesh.h"
#include "render/plan/scan.h"

namespace gvd {
namespace {

// Every program (render/gl/shaders/*.glsl) works in scene units relative to the window's min
// corner, with depth = value / depth_scale; glClipControl(ZERO_TO_ONE) keeps it unchanged
// into the depth buffer, with no [-1, 1] remapping to cost precision.

absl::Status GlError(const char* what) {
  GLenum e = glGetError();
  if (e == GL_NO_ERROR) return absl::OkStatus();
  return absl::InternalError(absl::StrCat(what, ": GL error 0x", absl::Hex(e)));
}

}  // namespace

absl::StatusOr<std::unique_ptr<RenderTarget>> RenderTarget::Create(uint32_t width,
                                                                   uint32_t height) {
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_size);
  if (width == 0 || height == 0 || width > uint32_t(max_size) || height > uint32_t(max_size)) {
    return absl::ResourceExhaustedError(absl::StrCat("render target ", width, "x", height,
                                                     " exceeds GL_MAX_RENDERBUFFER_SIZE ",
                                                     max_size));
  }
  std::unique_ptr<RenderTarget> t(new RenderTarget(width, height));
  t->fbo_ = gl::Framebuffer::Create();
  t->ids_ = gl::Renderbuffer::Create();
  t->depth_ = gl::Renderbuffer::Create();
  glBindRenderbuffer(GL_RENDERBUFFER, t->ids_.id());
  glRenderbufferStorage(GL_RENDERBUFFER, GL_R32UI, width, height);
  glBindRenderbuffer(GL_RENDERBUFFER, t->depth_.id());
  glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, width, height);
  glBindFramebuffer(GL_FRAMEBUFFER, t->fbo_.id());
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, t->ids_.id());
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, t->depth_.id());
  GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  if (auto s = GlError("creating the render target"); !s.ok()) return s;
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    return absl::InternalError(
        absl::StrCat("framebuffer incomplete: status 0x", absl::Hex(status)));
  }
  return t;
}

absl::StatusOr<Rasterizer::Program> Rasterizer::Link(const char* vertex, const char* fragment) {
  auto linked = gl::LinkProgram(vertex, fragment);
  if (!linked.ok()) return linked.status();
  Program p;
  p.program = std::move(*linked);
  p.u_scale = gl::Uniform(p.program, "u_scale");
  p.u_inv_depth = gl::Uniform(p.program, "u_inv_depth");
  p.u_pixel = gl::Uniform(p.program, "u_pixel");
  p.u_margin = gl::Uniform(p.program, "u_margin");
  p.u_origin = gl::Uniform(p.program, "u_origin");
  return p;
}

absl::StatusOr<std::unique_ptr<Rasterizer>> Rasterizer::Create(const DeviceInfo& device) {
  std::unique_ptr<Rasterizer> r(new Rasterizer());
  r->software_ = device.software;
  r->native_scan_ = device.software;
  for (auto [program, vertex, fragment] :
       {std::tuple{&r->cone_, shaders::kConeVert, shaders::kIdFrag},
        std::tuple{&r->tent_, shaders::kTentVert, shaders::kIdFrag},
        std::tuple{&r->exact_, shaders::kExactVert, shaders::kExactFrag},
        std::tuple{&r->exact_point_, shaders::kExactPointVert, shaders::kExactPointFrag},
        std::tuple{&r->resolve_, shaders::kResolveVert, shaders::kResolveFrag}}) {
    auto linked = Link(vertex, fragment);
    if (!linked.ok()) return linked.status();
    *program = std::move(*linked);
  }
  auto nearest = gl::LinkCompute(shaders::kNearestComp);
  if (!nearest.ok()) return nearest.status();
  r->nearest_ = std::move(*nearest);
  for (gl::Buffer& b : r->compute_buffers_) b = gl::Buffer::Create();
  GLint64 max_block = 0;
  glGetInteger64v(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &max_block);
  r->max_storage_block_ = max_block;
  r->vao_ = gl::VertexArray::Create();
  r->instances_ = gl::Buffer::Create();
  r->segments_ = gl::Buffer::Create();
  r->indirect_ = gl::Buffer::Create();
  // Two triangles spanning [0, 1]^2.
  const float quad[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 0, 0, 1, 1, 0, 0, 1, 0};
  r->quad_ = gl::Buffer::Create();
  glBindBuffer(GL_ARRAY_BUFFER, r->quad_.id());
  glBufferData(GL_ARRAY_BUFFER, sizeof quad, quad, GL_STATIC_DRAW);
  // Half a tent, (u, v, unused): the segment at v = 0, the far side at v = 1; and a strip
  // beyond the segment, v = -1 (tent.vert).
  const float tent[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 0, 0, 1, 1, 0, 0, 1, 0,
                        0, -1, 0, 1, -1, 0, 1, 0, 0, 0, -1, 0, 1, 0, 0, 0, 0, 0};
  r->tent_mesh_ = gl::Buffer::Create();
  glBindBuffer(GL_ARRAY_BUFFER, r->tent_mesh_.id());
  glBufferData(GL_ARRAY_BUFFER, sizeof tent, tent, GL_STATIC_DRAW);
  if (auto s = GlError("creating the rasterizer"); !s.ok()) return s;
  return r;
}

unsigned Rasterizer::ConeBuffer(uint32_t segments) {
  auto it = cones_.find(segments);
  if (it == cones_.end()) {
    // Two turns, so that any range of up to `segments` triangles is contiguous (FanTriangles).
    ConeMesh mesh = BuildUnitCone(segments);
    const size_t turn = mesh.vertices.size();
    mesh.vertices.resize(2 * turn);
    std::copy_n(mesh.vertices.begin(), turn, mesh.vertices.begin() + turn);
    gl::Buffer buffer = gl::Buffer::Create();
    glBindBuffer(GL_ARRAY_BUFFER, buffer.id());
    glBufferData(GL_ARRAY_BUFFER, mesh.vertices.size() * sizeof(float), mesh.vertices.data(),
                 GL_STATIC_DRAW);
    it = cones_.emplace(segments, std::move(buffer)).first;
  }
  return it->second.id();
}

absl::Status Rasterizer::Draw(const Grid& grid, const DrawParams& params, PixelRect scissor,
                              bool clear, const SlotTable& sites,
                              const std::vector<SiteDraw>& draws, RenderTarget& target,
                              uint32_t x0, uint32_t y0) {
  if (uint64_t{x0} + grid.width > target.width() || uint64_t{y0} + grid.height > target.height()) {
    return absl::InternalError("the grid does not fit in the render target");
  }
  if (scissor.empty()) return absl::OkStatus();
  // One instance of each program, laid out as its vertex shader's attributes 1, 2, ...: GLM's
  // float vectors are the shaders' vec2, vec3 and vec4.
  struct Cone {  // cone.vert
    glm::vec3 cone;  // (x, y, rho)
    glm::vec2 weight;
    glm::vec4 clip;
    uint32_t site;
  };
  struct Tent {  // tent.vert
    glm::vec4 ends;
    glm::vec3 tent;  // (half-width, m, a)
    glm::vec4 clip;
    glm::vec2 range;  // the part of ab drawn, as fractions of it
    uint32_t site;
  };
  struct Quad {  // exact.vert
    glm::vec4 rect;
    glm::vec3 weight;  // (m, a, reach)
    glm::vec4 first;
    glm::uvec4 info;
  };
  struct Square {  // exact_point.vert
    glm::vec4 rect;
    glm::vec2 point;
    glm::vec2 weight;
    uint32_t site;
  };
  static_assert(sizeof(Cone) == 10 * 4 && sizeof(Tent) == 14 * 4 && sizeof(Quad) == 15 * 4 &&
                sizeof(Square) == 9 * 4);
  struct Fans {
    std::vector<Cone> whole;        // drawn instanced
    std::vector<Cone> parts;        // each drawn over ranges[k] (an indirect draw each)
    std::vector<FanRange> ranges;
  };
  std::map<uint32_t, Fans> cones;  // by triangle count
  std::vector<Tent> tents;
  std::vector<Quad> quads;
  std::vector<Square> squares;
  std::vector<glm::vec4> segments;  // (a, b) per segment, for the quads (exact.frag)
  const Vec2 origin{grid.window.min_x, grid.window.min_y};
  auto rel = [&](Vec2 p) { return glm::vec2(p - origin); };
  for (const SiteDraw& d : draws) {
    const Site& site = *sites.get(d.slot);
    SiteShape shape = ShapeOf(grid, params, site, d);
    const glm::vec2 weight(site.multiplicative, site.additive);
    const uint32_t id = d.slot + 1;
    const Window c = grid.Area(d.clip);
    const glm::vec2 clip_lo = rel({c.min_x, c.min_y}), clip_hi = rel({c.max_x, c.max_y});
    // A rectangle cut to the clip; false when nothing of it is left.
    auto cut = [&](Vec2 lo, Vec2 hi, glm::vec4* rect) {
      *rect = glm::vec4(glm::max(rel(lo), clip_lo), glm::min(rel(hi), clip_hi));
      return rect->x < rect->z && rect->y < rect->w;
    };
    if (ExactPoint(params, site)) {
      // Half side: the radius with its margins (the shape's extent is the corners' reach).
      const double half = shape.extent / (std::numbers::sqrt2 * (1 + 0x1p-20));
      const Vec2 p = std::get<PointSite>(site.geometry).p;
      glm::vec4 rect;
      if (cut({p.x - half, p.y - half}, {p.x + half, p.y + half}, &rect)) {
        squares.push_back({rect, rel(p), weight, id});
      }
      continue;
    }
    if (shape.per_fragment) {
      Window b = BoundingBox(site.geometry);
      const double r = shape.extent;
      glm::vec4 rect;
      if (!cut({b.min_x - r, b.min_y - r}, {b.max_x + r, b.max_y + r}, &rect)) continue;
      PerFragmentSite f = PerFragmentOf(site, id, r, origin, &segments);
      quads.push_back({rect, f.weight, f.first, f.info});
      continue;
    }
    auto clip_of = [&](PixelRect r) {
      const Window c = grid.Area(r);
      return glm::vec4(rel({c.min_x, c.min_y}), rel({c.max_x, c.max_y}));
    };
    ForEachPieceDrawn(shape, d, site.geometry, [&](double e, PixelRect piece_clip, Vec2 p,
                                                   double from, double to) {
          const FanDraw fan = FanOf(shape.segments, from, to);
          Fans& fans = cones[fan.segments];
          const Cone cone{glm::vec3(rel(p), static_cast<float>(e)), weight, clip_of(piece_clip),
                          id};
          if (fan.whole()) {
            fans.whole.push_back(cone);
          } else {
            fans.parts.push_back(cone);
            fans.ranges.push_back(fan.range);
          }
        },
        [&](double e, PixelRect piece_clip, Vec2 p, Vec2 q, double from, double to) {
          tents.push_back({glm::vec4(rel(p), rel(q)), glm::vec3(e, weight), clip_of(piece_clip),
                           glm::vec2(from, to), id});
        });
  }
  glBindFramebuffer(GL_FRAMEBUFFER, target.framebuffer());
  glViewport(x0, y0, grid.width, grid.height);
  glEnable(GL_SCISSOR_TEST);
  glScissor(x0 + scissor.x0, y0 + scissor.y0, scissor.width(), scissor.height());
  glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  glEnable(GL_DEPTH_TEST);
  const bool farthest = params.diagram == Diagram::kFarthest;
  glDepthFunc(farthest ? GL_GREATER : GL_LESS);
  glDepthMask(GL_TRUE);
  glDisable(GL_BLEND);
  glDisable(GL_CULL_FACE);
  if (clear) {
    const GLuint zero_id[4] = {0, 0, 0, 0};
    glClearBufferuiv(GL_COLOR, 0, zero_id);
    glClearBufferfi(GL_DEPTH_STENCIL, 0, farthest ? 0.0f : 1.0f, 0);
  }
  const glm::vec2 scale(2 / grid.window.width(), 2 / grid.window.height());
  const glm::vec2 pixel(grid.pixel_width(), grid.pixel_height());
  const glm::vec2 target_origin(x0, y0);
  const float inv_depth = static_cast<float>(1 / params.depth_scale);
  auto use = [&](const Program& p) {
    glUseProgram(p.id());
    glUniform2fv(p.u_scale, 1, glm::value_ptr(scale));
    glUniform1f(p.u_inv_depth, inv_depth);
  };
  // Binds `mesh` as attribute 0 and `data` (n instances of `stride` bytes) as attributes
  // 1.. with the given float component counts, then the uint components.
  auto bind = [&](unsigned mesh, const void* data, size_t n, size_t stride,
                  std::initializer_list<int> floats, int uints) {
    glBindBuffer(GL_ARRAY_BUFFER, mesh);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), nullptr);
    glVertexAttribDivisor(0, 0);
    glBindBuffer(GL_ARRAY_BUFFER, instances_.id());
    glBufferData(GL_ARRAY_BUFFER, n * stride, data, GL_STREAM_DRAW);
    GLuint location = 1;
    size_t offset = 0;
    for (int count : floats) {
      glEnableVertexAttribArray(location);
      glVertexAttribPointer(location, count, GL_FLOAT, GL_FALSE, static_cast<GLsizei>(stride),
                            reinterpret_cast<void*>(offset));
      glVertexAttribDivisor(location++, 1);
      offset += count * sizeof(float);
    }
    glEnableVertexAttribArray(location);
    glVertexAttribIPointer(location, uints, GL_UNSIGNED_INT, static_cast<GLsizei>(stride),
                           reinterpret_cast<void*>(offset));
    glVertexAttribDivisor(location, 1);
  };
  glBindVertexArray(vao_.id());
  for (GLuint location = 0; location < 6; ++location) glDisableVertexAttribArray(location);
  // The cones and tents are cut to their sites' clips (cone.vert and tent.vert write the
  // distances); the other programs write none, and their rectangles are cut above.
  for (GLenum plane = 0; plane < 4; ++plane) glEnable(GL_CLIP_DISTANCE0 + plane);
  if (!cones.empty()) {
    use(cone_);
    // glMultiDrawArraysIndirect's command; the instances are the whole fans, then the parts.
    struct Command {
      GLuint count, instances, first, base_instance;
    };
    std::vector<Command> commands;
    for (auto& [n, fans] : cones) {
      const size_t whole = fans.whole.size();
      fans.whole.insert(fans.whole.end(), fans.parts.begin(), fans.parts.end());
      bind(ConeBuffer(n), fans.whole.data(), fans.whole.size(), sizeof(Cone), {3, 2, 4}, 1);
      if (whole > 0) {
        glDrawArraysInstanced(GL_TRIANGLES, 0, static_cast<GLsizei>(n * 3),
                              static_cast<GLsizei>(whole));
      }
      if (fans.parts.empty()) continue;
      commands.clear();
      for (size_t k = 0; k < fans.ranges.size(); ++k) {
        commands.push_back({3 * fans.ranges[k].count, 1, 3 * fans.ranges[k].first,
                            static_cast<GLuint>(whole + k)});
      }
      glBindBuffer(GL_DRAW_INDIRECT_BUFFER, indirect_.id());
      glBufferData(GL_DRAW_INDIRECT_BUFFER, commands.size() * sizeof(Command), commands.data(),
                   GL_STREAM_DRAW);
      glMultiDrawArraysIndirect(GL_TRIANGLES, nullptr, static_cast<GLsizei>(commands.size()), 0);
      glBindBuffer(GL_DRAW_INDIRECT_BUFFER, 0);
    }
  }
  if (!tents.empty()) {
    use(tent_);
    glUniform1f(gl::Uniform(tent_.program, "u_overhang"),
                static_cast<float>(grid.pixel_size() / 64));
    bind(tent_mesh_.id(), tents.data(), tents.size(), sizeof(Tent), {4, 3, 4, 2}, 1);
    glDrawArraysInstanced(GL_TRIANGLES, 0, 12, static_cast<GLsizei>(tents.size()));
  }
  for (GLenum plane = 0; plane < 4; ++plane) glDisable(GL_CLIP_DISTANCE0 + plane);
  if (!squares.empty()) {
    use(exact_point_);
    glUniform2fv(exact_point_.u_pixel, 1, glm::value_ptr(pixel));
    glUniform2fv(exact_point_.u_origin, 1, glm::value_ptr(target_origin));
    bind(quad_.id(), squares.data(), squares.size(), sizeof(Square), {4, 2, 2}, 1);
    glDrawArraysInstanced(GL_TRIANGLES, 0, 6, static_cast<GLsizei>(squares.size()));
  }
  if (!quads.empty()) {
    use(exact_);
    glUniform2fv(exact_.u_pixel, 1, glm::value_ptr(pixel));
    glUniform1f(exact_.u_margin, static_cast<float>(DrawMargin(grid)));
    glUniform2fv(exact_.u_origin, 1, glm::value_ptr(target_origin));
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, segments_.id());
    glBufferData(GL_SHADER_STORAGE_BUFFER, segments.size() * sizeof(glm::vec4), segments.data(),
                 GL_STREAM_DRAW);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, segments_.id());
    bind(quad_.id(), quads.data(), quads.size(), sizeof(Quad), {4, 3, 4}, 4);
    glDrawArraysInstanced(GL_TRIANGLES, 0, 6, static_cast<GLsizei>(quads.size()));
  }
  glDisable(GL_SCISSOR_TEST);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  return GlError("drawing distance meshes");
}

absl::Status Rasterizer::Compute(const Grid& grid, const DrawParams& params,
                                 const SlotTable& sites, const std::vector<SiteDraw>& draws,
                                 const TileLists& lists, RenderTarget& target,
                                 std::vector<uint32_t>* ids, std::vector<float>* distances) {
  const uint32_t tiles_x = (grid.width + kScanTile - 1) / kScanTile;
  const uint32_t tiles_y = (grid.height + kScanTile - 1) / kScanTile;
  if (grid.width > target.width() || grid.height > target.height() ||
      lists.offsets.size() != 3 * (size_t{tiles_x} * tiles_y + 1)) {
    return absl::InternalError("the grid or its tiles do not match the render target");
  }
  auto upload = [](const gl::Buffer& buffer, GLuint binding, const void* data, size_t bytes) {
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, buffer.id());
    glBufferData(GL_SHADER_STORAGE_BUFFER, static_cast<GLsizeiptr>(bytes), data, GL_STREAM_DRAW);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding, buffer.id());
  };
  const size_t pixels = grid.pixel_count();
  ScanSites scan;
  {
    GlTurn::Away off_gl(gl_turn_);  // CPU only: the sites' records
    scan = ScanSitesOf(grid, params, sites, draws);
  }
  std::vector<ComputeSite>& records = scan.sites;
  std::vector<glm::vec4>& segments = scan.segments;
  // What the GL's storage buffers must hold: the resolve's pixels always, the lists too for
  // the shader.
  std::vector<std::pair<size_t, const char*>> buffers = {
      {pixels * sizeof(uint32_t), "the pixels' ids"}};
  if (!native_scan_) {
    buffers.insert(buffers.end(),
                   {{segments.size() * sizeof(glm::vec4), "the segments"},
                    {records.size() * sizeof(ComputeSite), "the sites"},
                    {lists.points.size() * sizeof(TileLists::Point), "the tiles' points"},
                    {lists.sites.size() * sizeof(uint32_t), "the tiles' sites"},
                    {lists.segments.size() * sizeof(TileLists::Segment), "the tiles' segments"}});
  }
  for (auto [bytes, what] : buffers) {
    if (bytes > static_cast<uint64_t>(max_storage_block_)) {
      return absl::ResourceExhaustedError(
          absl::StrCat(what, " take ", bytes, " bytes; GL_MAX_SHADER_STORAGE_BLOCK_SIZE is ",
                       max_storage_block_));
    }
  }
  if (native_scan_) {
    // The shader's loop as native code on every core; the result goes where the shader
    // would have written it. No GL meanwhile: other render threads may have their turn.
    {
      GlTurn::Away off_gl(gl_turn_);
      ScanTiles(grid, grid.all(), lists, scan, static_cast<float>(params.depth_scale), ids,
                distances);
    }
    upload(compute_buffers_[3], 4, ids->data(), pixels * sizeof(uint32_t));
    upload(compute_buffers_[4], 5, distances->data(), pixels * sizeof(float));
    return Resolve(grid, params, target);
  }
  if (segments.empty()) segments.emplace_back();  // no buffer may be empty
  if (records.empty()) records.emplace_back();
  const uint32_t no_site = 0;
  const TileLists::Point no_point{};
  const TileLists::Segment no_segment{};
  upload(segments_, 0, segments.data(), segments.size() * sizeof(glm::vec4));
  upload(compute_buffers_[0], 1, records.data(), records.size() * sizeof(ComputeSite));
  upload(compute_buffers_[1], 2, lists.offsets.data(), lists.offsets.size() * sizeof(uint32_t));
  upload(compute_buffers_[2], 3, lists.sites.empty() ? &no_site : lists.sites.data(),
         std::max<size_t>(lists.sites.size(), 1) * sizeof(uint32_t));
  upload(compute_buffers_[5], 6, lists.points.empty() ? &no_point : lists.points.data(),
         std::max<size_t>(lists.points.size(), 1) * sizeof(TileLists::Point));
  upload(compute_buffers_[6], 7, lists.segments.empty() ? &no_segment : lists.segments.data(),
         std::max<size_t>(lists.segments.size(), 1) * sizeof(TileLists::Segment));
  upload(compute_buffers_[3], 4, nullptr, pixels * sizeof(uint32_t));
  upload(compute_buffers_[4], 5, nullptr, pixels * sizeof(float));
  glUseProgram(nearest_.id());
  glUniform2ui(gl::Uniform(nearest_, "u_size"), grid.width, grid.height);
  glUniform2f(gl::Uniform(nearest_, "u_pixel"), static_cast<float>(grid.pixel_width()),
              static_cast<float>(grid.pixel_height()));
  glUniform1f(gl::Uniform(nearest_, "u_margin"), static_cast<float>(DrawMargin(grid)));
  glUniform1f(gl::Uniform(nearest_, "u_none"), static_cast<float>(params.depth_scale));
  glDispatchCompute(tiles_x, tiles_y, 1);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
  // The frame's copy, then the target's: a triangle over the grid writes each pixel's id and
  // depth from the same buffers.
  ids->resize(pixels);
  distances->resize(pixels);
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, compute_buffers_[3].id());
  glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, pixels * sizeof(uint32_t), ids->data());
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, compute_buffers_[4].id());
  glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, pixels * sizeof(float), distances->data());
  return Resolve(grid, params, target);
}

absl::Status Rasterizer::Resolve(const Grid& grid, const DrawParams& params,
                                 RenderTarget& target) {
  glBindFramebuffer(GL_FRAMEBUFFER, target.framebuffer());
  glViewport(0, 0, grid.width, grid.height);
  glDisable(GL_SCISSOR_TEST);
  glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  const GLuint zero_id[4] = {0, 0, 0, 0};
  glClearBufferuiv(GL_COLOR, 0, zero_id);
  glClearBufferfi(GL_DEPTH_STENCIL, 0, 1.0f, 0);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_ALWAYS);
  glDepthMask(GL_TRUE);
  glDisable(GL_BLEND);
  glDisable(GL_CULL_FACE);
  glUseProgram(resolve_.id());
  glUniform1ui(gl::Uniform(resolve_.program, "u_width"), grid.width);
  glUniform1f(resolve_.u_inv_depth, static_cast<float>(1 / params.depth_scale));
  glBindVertexArray(vao_.id());
  for (GLuint location = 0; location < 6; ++location) glDisableVertexAttribArray(location);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  return GlError("computing a render");
}

absl::Status Rasterizer::ReadBack(RenderTarget& target, PixelRect rect, double depth_scale,
                                  std::vector<uint32_t>* ids, std::vector<float>* distances) {
  ids->resize(rect.area());
  distances->resize(rect.area());
  if (rect.empty()) return absl::OkStatus();
  glBindFramebuffer(GL_FRAMEBUFFER, target.framebuffer());
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  glReadPixels(rect.x0, rect.y0, rect.width(), rect.height(), GL_RED_INTEGER, GL_UNSIGNED_INT,
               ids->data());
  glReadPixels(rect.x0, rect.y0, rect.width(), rect.height(), GL_DEPTH_COMPONENT, GL_FLOAT,
               distances->data());
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  for (float& d : *distances) d = static_cast<float>(d * depth_scale);
  return GlError("reading back the frame");
}

}  // namespace gvd

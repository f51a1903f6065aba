#include "render/raster.h"

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <chrono>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "render/exact.h"
#include "render/scene_raster.h"
#include "render/mesh.h"

namespace gvd {
namespace {

// Point cones, instanced: `unit` is a vertex of the unit cone, `instance` = (x, y, rho) with
// x, y relative to the window's min corner in scene units, `site` = site index + 1.
// Depth is distance / depth_scale; glClipControl(ZERO_TO_ONE) keeps it unchanged into the
// depth buffer, with no [-1, 1] remapping to cost precision.
constexpr const char* kVertexShader = R"(#version 450 core
layout(location = 0) in vec3 unit;
layout(location = 1) in vec3 instance;
layout(location = 2) in uint site;
uniform vec2 u_scale;
uniform float u_inv_depth;
flat out uint v_site;
void main() {
  vec2 p = instance.xy + instance.z * unit.xy;
  gl_Position = vec4(p * u_scale - 1.0, unit.z * instance.z * u_inv_depth, 1.0);
  v_site = site;
}
)";

constexpr const char* kFragmentShader = R"(#version 450 core
flat in uint v_site;
layout(location = 0) out uint o_site;
void main() { o_site = v_site; }
)";

// Exact mode: the same instances drawn as quads (`unit` spans [-1, 1]^2) whose fragments
// evaluate the distance to the site analytically, from the pixel centre gl_FragCoord.
constexpr const char* kExactVertexShader = R"(#version 450 core
layout(location = 0) in vec3 unit;
layout(location = 1) in vec3 instance;
layout(location = 2) in uint site;
uniform vec2 u_scale;
uniform vec2 u_inv_pixel;
flat out uint v_site;
flat out vec2 v_site_px;
void main() {
  vec2 p = instance.xy + instance.z * unit.xy;
  gl_Position = vec4(p * u_scale - 1.0, 0.0, 1.0);
  v_site = site;
  v_site_px = instance.xy * u_inv_pixel;
}
)";

constexpr const char* kExactFragmentShader = R"(#version 450 core
flat in uint v_site;
flat in vec2 v_site_px;
uniform vec2 u_pixel;
uniform float u_inv_depth;
layout(location = 0) out uint o_site;
void main() {
  gl_FragDepth = length((gl_FragCoord.xy - v_site_px) * u_pixel) * u_inv_depth;
  o_site = v_site;
}
)";

absl::Status GlError(const char* what) {
  GLenum e = glGetError();
  if (e == GL_NO_ERROR) return absl::OkStatus();
  return absl::InternalError(absl::StrCat(what, ": GL error 0x", absl::Hex(e)));
}

absl::StatusOr<GLuint> Compile(GLenum kind, const char* source) {
  GLuint shader = glCreateShader(kind);
  glShaderSource(shader, 1, &source, nullptr);
  glCompileShader(shader);
  GLint ok = 0;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetShaderInfoLog(shader, sizeof log, nullptr, log);
    glDeleteShader(shader);
    return absl::InternalError(absl::StrCat("shader compilation failed: ", log));
  }
  return shader;
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
  glGenFramebuffers(1, &t->fbo_);
  glGenRenderbuffers(1, &t->ids_);
  glGenRenderbuffers(1, &t->depth_);
  glBindRenderbuffer(GL_RENDERBUFFER, t->ids_);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_R32UI, width, height);
  glBindRenderbuffer(GL_RENDERBUFFER, t->depth_);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, width, height);
  glBindFramebuffer(GL_FRAMEBUFFER, t->fbo_);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, t->ids_);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, t->depth_);
  GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  if (auto s = GlError("creating the render target"); !s.ok()) return s;
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    return absl::InternalError(
        absl::StrCat("framebuffer incomplete: status 0x", absl::Hex(status)));
  }
  return t;
}

RenderTarget::~RenderTarget() {
  glDeleteFramebuffers(1, &fbo_);
  glDeleteRenderbuffers(1, &ids_);
  glDeleteRenderbuffers(1, &depth_);
}

absl::StatusOr<Rasterizer::Program> Rasterizer::Link(const char* vertex, const char* fragment) {
  auto vs = Compile(GL_VERTEX_SHADER, vertex);
  if (!vs.ok()) return vs.status();
  auto fs = Compile(GL_FRAGMENT_SHADER, fragment);
  if (!fs.ok()) {
    glDeleteShader(*vs);
    return fs.status();
  }
  Program p;
  p.id = glCreateProgram();
  glAttachShader(p.id, *vs);
  glAttachShader(p.id, *fs);
  glLinkProgram(p.id);
  glDeleteShader(*vs);
  glDeleteShader(*fs);
  GLint ok = 0;
  glGetProgramiv(p.id, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetProgramInfoLog(p.id, sizeof log, nullptr, log);
    glDeleteProgram(p.id);
    return absl::InternalError(absl::StrCat("shader link failed: ", log));
  }
  p.u_scale = glGetUniformLocation(p.id, "u_scale");
  p.u_inv_depth = glGetUniformLocation(p.id, "u_inv_depth");
  p.u_pixel = glGetUniformLocation(p.id, "u_pixel");
  p.u_inv_pixel = glGetUniformLocation(p.id, "u_inv_pixel");
  return p;
}

absl::StatusOr<std::unique_ptr<Rasterizer>> Rasterizer::Create() {
  std::unique_ptr<Rasterizer> r(new Rasterizer());
  auto mesh = Link(kVertexShader, kFragmentShader);
  if (!mesh.ok()) return mesh.status();
  r->mesh_ = *mesh;
  auto exact = Link(kExactVertexShader, kExactFragmentShader);
  if (!exact.ok()) return exact.status();
  r->exact_ = *exact;
  glGenVertexArrays(1, &r->vao_);
  glGenBuffers(1, &r->instances_);
  // Two triangles spanning [-1, 1]^2, in the cone vertices' layout.
  const float quad[] = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, -1, 0, 1, 1, 0, -1, 1, 0};
  glGenBuffers(1, &r->quad_);
  glBindBuffer(GL_ARRAY_BUFFER, r->quad_);
  glBufferData(GL_ARRAY_BUFFER, sizeof quad, quad, GL_STATIC_DRAW);
  if (auto s = GlError("creating the rasterizer"); !s.ok()) return s;
  return r;
}

Rasterizer::~Rasterizer() {
  for (auto& [n, buffer] : cones_) glDeleteBuffers(1, &buffer);
  glDeleteBuffers(1, &quad_);
  glDeleteBuffers(1, &instances_);
  glDeleteVertexArrays(1, &vao_);
  glDeleteProgram(mesh_.id);
  glDeleteProgram(exact_.id);
}

unsigned Rasterizer::ConeBuffer(uint32_t segments) {
  auto it = cones_.find(segments);
  if (it == cones_.end()) {
    ConeMesh mesh = BuildUnitCone(segments);
    GLuint buffer = 0;
    glGenBuffers(1, &buffer);
    glBindBuffer(GL_ARRAY_BUFFER, buffer);
    glBufferData(GL_ARRAY_BUFFER, mesh.vertices.size() * sizeof(float), mesh.vertices.data(),
                 GL_STATIC_DRAW);
    it = cones_.emplace(segments, buffer).first;
  }
  return it->second;
}

namespace {

// Fans are drawn with one of these triangle counts (or a multiple of 4096 beyond): the next
// one up from what a site needs, so that sites share a few instanced draws. More triangles
// than needed only lower the error.
uint32_t SegmentBucket(uint32_t needed) {
  static constexpr uint32_t kBuckets[] = {3,   4,   6,   8,   12,   16,   24,   32,   48,  64,
                                          96,  128, 192, 256, 384,  512,  768,  1024, 1536,
                                          2048, 3072, 4096};
  for (uint32_t b : kBuckets) {
    if (needed <= b) return b;
  }
  return std::min(kMaxConeSegments, (needed + 4095) / 4096 * 4096);
}

}  // namespace

Rasterizer::ConeShape Rasterizer::Shape(const Grid& grid, double radius, double eps,
                                        RenderMode mode) const {
  // A sixteenth of a pixel beyond the proven radius keeps centres on the edge inside,
  // whatever the rasterizer's snapping (1/256 pixel). Scaled by extent = r * k, the fan
  // covers radius r; the factor 1 + 2^-20 absorbs the rounding of the float ring vertices,
  // which can fall a few ulps inside the unit circle.
  double r = radius + grid.pixel_size() / 16;
  if (mode == RenderMode::kExact) {
    // A quad of half-side r: its corners, sqrt(2) r away, bound the distances it writes.
    return {2, 1, r * std::numbers::sqrt2 * (1 + 0x1p-20), r};
  }
  uint32_t n = SegmentBucket(ConeSegments(r + eps, eps));
  double k = 1 / std::cos(std::numbers::pi / n);
  return {n, k, r * k * (1 + 0x1p-20), r * k * (1 + 0x1p-20)};
}

absl::Status Rasterizer::Draw(const Grid& grid, double eps, RenderMode mode, double depth_scale,
                              PixelRect scissor, bool clear, const std::vector<ConeDraw>& cones,
                              RenderTarget& target) {
  if (target.width() != grid.width || target.height() != grid.height) {
    return absl::InternalError("render target does not match the grid");
  }
  if (scissor.empty()) return absl::OkStatus();
  struct Instance {
    float x, y, rho;
    uint32_t site;
  };
  std::map<uint32_t, std::vector<Instance>> buckets;
  for (const ConeDraw& c : cones) {
    ConeShape shape = Shape(grid, c.radius, eps, mode);
    buckets[shape.segments].push_back({static_cast<float>(c.site.x - grid.window.min_x),
                                       static_cast<float>(c.site.y - grid.window.min_y),
                                       static_cast<float>(shape.scale), c.slot + 1});
  }
  glBindFramebuffer(GL_FRAMEBUFFER, target.framebuffer());
  glViewport(0, 0, grid.width, grid.height);
  glEnable(GL_SCISSOR_TEST);
  glScissor(scissor.x0, scissor.y0, scissor.width(), scissor.height());
  glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDepthMask(GL_TRUE);
  glDisable(GL_BLEND);
  glDisable(GL_CULL_FACE);
  if (clear) {
    const GLuint zero_id[4] = {0, 0, 0, 0};
    glClearBufferuiv(GL_COLOR, 0, zero_id);
    glClearBufferfi(GL_DEPTH_STENCIL, 0, 1.0f, 0);
  }
  const Program& program = mode == RenderMode::kExact ? exact_ : mesh_;
  glUseProgram(program.id);
  glUniform2f(program.u_scale, static_cast<float>(2 / grid.window.width()),
              static_cast<float>(2 / grid.window.height()));
  glUniform1f(program.u_inv_depth, static_cast<float>(1 / depth_scale));
  if (mode == RenderMode::kExact) {
    glUniform2f(program.u_pixel, static_cast<float>(grid.pixel_width()),
                static_cast<float>(grid.pixel_height()));
    glUniform2f(program.u_inv_pixel, static_cast<float>(1 / grid.pixel_width()),
                static_cast<float>(1 / grid.pixel_height()));
  }
  glBindVertexArray(vao_);
  for (const auto& [segments, instances] : buckets) {
    glBindBuffer(GL_ARRAY_BUFFER, mode == RenderMode::kExact ? quad_ : ConeBuffer(segments));
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), nullptr);
    glVertexAttribDivisor(0, 0);
    glBindBuffer(GL_ARRAY_BUFFER, instances_);
    glBufferData(GL_ARRAY_BUFFER, instances.size() * sizeof(Instance), instances.data(),
                 GL_STREAM_DRAW);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, sizeof(Instance), nullptr);
    glVertexAttribDivisor(1, 1);
    glEnableVertexAttribArray(2);
    glVertexAttribIPointer(2, 1, GL_UNSIGNED_INT, sizeof(Instance),
                           reinterpret_cast<void*>(offsetof(Instance, site)));
    glVertexAttribDivisor(2, 1);
    glDrawArraysInstanced(GL_TRIANGLES, 0, static_cast<GLsizei>(segments * 3),
                          static_cast<GLsizei>(instances.size()));
  }
  glDisable(GL_SCISSOR_TEST);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  return GlError("drawing distance meshes");
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

absl::StatusOr<std::shared_ptr<const Frame>> Rasterizer::Render(const Grid& grid, double eps,
                                                                uint64_t version,
                                                                const SiteTable& sites,
                                                                RenderStats* stats,
                                                                RenderMode mode) {
  auto scene = SceneRaster::Create(grid, eps, mode);
  if (!scene.ok()) return scene.status();
  std::vector<SiteChange> changes;
  changes.reserve(sites.size());
  for (const Site& s : sites) changes.push_back({s.id, s.geometry});
  return (*scene)->Apply(*this, version, std::move(changes), stats);
}

}  // namespace gvd

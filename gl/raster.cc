#include "gl/raster.h"

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "geometry/coverage.h"
#include "geometry/exact.h"
#include "gl/scene_raster.h"
#include "geometry/mesh.h"

namespace gvd {
namespace {

// Every program works in scene units relative to the window's min corner, with depth =
// value / depth_scale; glClipControl(ZERO_TO_ONE) keeps it unchanged into the depth buffer,
// with no [-1, 1] remapping to cost precision.

// Vertex cones, instanced: `unit` is a vertex of the unit cone, `cone` = (x, y, rho),
// `weight` = (m, a), `site` = slot + 1. Height m * rho * z + a.
constexpr const char* kConeVertexShader = R"(#version 450 core
layout(location = 0) in vec3 unit;
layout(location = 1) in vec3 cone;
layout(location = 2) in vec2 weight;
layout(location = 3) in uint site;
uniform vec2 u_scale;
uniform float u_inv_depth;
flat out uint v_site;
void main() {
  vec2 p = cone.xy + cone.z * unit.xy;
  float value = weight.x * cone.z * unit.z + weight.y;
  gl_Position = vec4(p * u_scale - 1.0, value * u_inv_depth, 1.0);
  v_site = site;
}
)";

// Edge tents, instanced: `unit` = (u, v, |v|) spans the segment (u in [0, 1]) and its
// normal (v in [-1, 1]); `ends` = (a, b), `tent` = (half-width r, m, a). Each half is a plane,
// so the interpolated height is the distance to the segment's line, exactly.
constexpr const char* kTentVertexShader = R"(#version 450 core
layout(location = 0) in vec3 unit;
layout(location = 1) in vec4 ends;
layout(location = 2) in vec3 tent;
layout(location = 3) in uint site;
uniform vec2 u_scale;
uniform float u_inv_depth;
flat out uint v_site;
void main() {
  vec2 ab = ends.zw - ends.xy;
  vec2 n = vec2(-ab.y, ab.x) / length(ab);
  vec2 p = ends.xy + unit.x * ab + unit.y * tent.x * n;
  float value = tent.y * tent.x * unit.z + tent.z;
  gl_Position = vec4(p * u_scale - 1.0, value * u_inv_depth, 1.0);
  v_site = site;
}
)";

constexpr const char* kIdFragmentShader = R"(#version 450 core
flat in uint v_site;
layout(location = 0) out uint o_site;
void main() { o_site = v_site; }
)";

// Per-fragment sites, instanced quads: `rect` = (x0, y0, x1, y1), `weight` = (m, a, reach),
// `first` = the site's first segment (also in the buffer), `info` = (site, index of the first
// segment, segment count, side: 0 both, 1 outside, 2 inside). The
// fragment takes the least distance over the site's segments (a point is one of length 0),
// tests the polygon's side by the even-odd rule, and writes m d + a as depth.
constexpr const char* kExactVertexShader = R"(#version 450 core
layout(location = 0) in vec3 unit;
layout(location = 1) in vec4 rect;
layout(location = 2) in vec3 weight;
layout(location = 3) in vec4 first;
layout(location = 4) in uvec4 info;
uniform vec2 u_scale;
flat out uvec4 v_info;
flat out vec3 v_weight;
flat out vec4 v_first;
void main() {
  vec2 p = mix(rect.xy, rect.zw, unit.xy);
  gl_Position = vec4(p * u_scale - 1.0, 0.0, 1.0);
  v_info = info;
  v_weight = weight;
  v_first = first;
}
)";

// Points with no max_distance, per fragment: instanced squares of half side r around each
// point (rect = (x, y, r)), weight = (m, a); nothing to discard, no buffer to read, so the
// fragment is one distance. The square's corners, sqrt(2) r away, bound what it writes.
constexpr const char* kExactPointVertexShader = R"(#version 450 core
layout(location = 0) in vec3 unit;
layout(location = 1) in vec3 square;
layout(location = 2) in vec2 weight;
layout(location = 3) in uint site;
uniform vec2 u_scale;
flat out uint v_site;
flat out vec2 v_point;
flat out vec2 v_weight;
void main() {
  vec2 p = square.xy + square.z * (2.0 * unit.xy - 1.0);
  gl_Position = vec4(p * u_scale - 1.0, 0.0, 1.0);
  v_site = site;
  v_point = square.xy;
  v_weight = weight;
}
)";

constexpr const char* kExactPointFragmentShader = R"(#version 450 core
flat in uint v_site;
flat in vec2 v_point;
flat in vec2 v_weight;
uniform vec2 u_pixel;
uniform vec2 u_origin;
uniform float u_inv_depth;
layout(location = 0) out uint o_site;
void main() {
  vec2 p = (gl_FragCoord.xy - u_origin) * u_pixel;
  gl_FragDepth = (v_weight.x * length(p - v_point) + v_weight.y) * u_inv_depth;
  o_site = v_site;
}
)";

constexpr const char* kExactFragmentShader = R"(#version 450 core
layout(std430, binding = 0) readonly buffer Segments { vec4 segments[]; };
flat in uvec4 v_info;
flat in vec3 v_weight;
flat in vec4 v_first;
uniform vec2 u_pixel;
uniform vec2 u_origin;
uniform float u_inv_depth;
uniform float u_margin;
layout(location = 0) out uint o_site;
vec2 p;
float d = 3.0e38;
bool inside = false;
void visit(vec4 s) {
  vec2 ab = s.zw - s.xy, ap = p - s.xy;
  float len2 = dot(ab, ab);
  float t = len2 > 0.0 ? clamp(dot(ap, ab) / len2, 0.0, 1.0) : 0.0;
  d = min(d, length(ap - t * ab));
  if ((s.y > p.y) != (s.w > p.y) && p.x < s.x + (p.y - s.y) / (s.w - s.y) * (s.z - s.x)) {
    inside = !inside;
  }
}
void main() {
  p = (gl_FragCoord.xy - u_origin) * u_pixel;  // the grid's pixel (0, 0) is at u_origin
  visit(v_first);  // a point's only segment comes with the instance: no buffer read
  for (uint i = v_info.y + 1u; i < v_info.y + v_info.z; ++i) visit(segments[i]);
  if (d > v_weight.z) discard;
  if (v_info.w != 0u && d > u_margin && inside != (v_info.w == 2u)) discard;
  gl_FragDepth = (v_weight.x * d + v_weight.y) * u_inv_depth;
  o_site = v_info.x;
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
  p.u_margin = glGetUniformLocation(p.id, "u_margin");
  p.u_origin = glGetUniformLocation(p.id, "u_origin");
  return p;
}

absl::StatusOr<std::unique_ptr<Rasterizer>> Rasterizer::Create() {
  std::unique_ptr<Rasterizer> r(new Rasterizer());
  for (auto [program, vertex, fragment] :
       {std::tuple{&r->cone_, kConeVertexShader, kIdFragmentShader},
        std::tuple{&r->tent_, kTentVertexShader, kIdFragmentShader},
        std::tuple{&r->exact_, kExactVertexShader, kExactFragmentShader},
        std::tuple{&r->exact_point_, kExactPointVertexShader, kExactPointFragmentShader}}) {
    auto linked = Link(vertex, fragment);
    if (!linked.ok()) return linked.status();
    *program = *linked;
  }
  glGenVertexArrays(1, &r->vao_);
  glGenBuffers(1, &r->instances_);
  glGenBuffers(1, &r->segments_);
  // Two triangles spanning [0, 1]^2.
  const float quad[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 0, 0, 1, 1, 0, 0, 1, 0};
  glGenBuffers(1, &r->quad_);
  glBindBuffer(GL_ARRAY_BUFFER, r->quad_);
  glBufferData(GL_ARRAY_BUFFER, sizeof quad, quad, GL_STATIC_DRAW);
  // The two halves of a tent, (u, v, |v|): the segment at v = 0, the far sides at |v| = 1.
  const float tent[] = {0, 0, 0, 1, 0, 0, 1, 1, 1, 0, 0, 0, 1, 1, 1, 0, 1, 1,
                        0, 0, 0, 1, -1, 1, 1, 0, 0, 0, 0, 0, 0, -1, 1, 1, -1, 1};
  glGenBuffers(1, &r->tent_mesh_);
  glBindBuffer(GL_ARRAY_BUFFER, r->tent_mesh_);
  glBufferData(GL_ARRAY_BUFFER, sizeof tent, tent, GL_STATIC_DRAW);
  if (auto s = GlError("creating the rasterizer"); !s.ok()) return s;
  return r;
}

Rasterizer::~Rasterizer() {
  for (auto& [n, buffer] : cones_) glDeleteBuffers(1, &buffer);
  for (unsigned b : {quad_, tent_mesh_, instances_, segments_}) glDeleteBuffers(1, &b);
  glDeleteVertexArrays(1, &vao_);
  for (const Program* p : {&cone_, &tent_, &exact_, &exact_point_}) glDeleteProgram(p->id);
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

namespace {

// Whether a site is drawn per fragment (see RenderMode).
bool PerFragment(const DrawParams& params, const Site& site) {
  if (params.mode == RenderMode::kExact) return true;
  if (const auto* poly = std::get_if<PolygonSite>(&site.geometry)) {
    if (poly->side != Side::kBoth) return true;
  }
  return params.diagram == Diagram::kFarthest && !std::holds_alternative<PointSite>(site.geometry);
}

// A point drawn per fragment with no max_distance to honour: a square of its own.
bool ExactPoint(const DrawParams& params, const Site& site) {
  return params.mode == RenderMode::kExact && std::isinf(site.max_distance) &&
         std::holds_alternative<PointSite>(site.geometry);
}

// Calls f(p) for each vertex of the geometry that gets a cone in kMesh, and g(a, b) for each
// edge of positive length that gets a tent.
template <class F, class G>
void ForEachPiece(const Geometry& geometry, F&& f, G&& g) {
  if (const auto* p = std::get_if<PointSite>(&geometry)) {
    f(p->p);
    return;
  }
  bool first = true;
  const bool closed = std::holds_alternative<PolygonSite>(geometry);
  ForEachSegment(geometry, [&](Vec2 a, Vec2 b) {
    if (first && !closed) f(a);  // a polygon's first vertex is the last edge's end
    first = false;
    f(b);
    if (a.x != b.x || a.y != b.y) g(a, b);
  });
}

}  // namespace

SiteShape Rasterizer::Shape(const Grid& grid, const DrawParams& params, const Site& site,
                            double radius) const {
  // A sixteenth of a pixel beyond the proven radius keeps centres on the edge inside,
  // whatever the rasterizer's snapping (1/256 pixel), and 2^-18 of the largest float
  // coordinate involved keeps them inside whatever the rounding of positions and distances
  // (which dominates in deep zoom windows). Scaled by extent = r * k, a fan covers radius r;
  // the factor 1 + 2^-20 absorbs the rounding of the float ring vertices, which can fall a
  // few ulps inside the unit circle.
  const Window box = BoundingBox(site.geometry);
  const Window& w = grid.window;
  const double scale = std::max({std::abs(box.min_x - w.min_x), std::abs(box.max_x - w.min_x),
                                 std::abs(box.min_y - w.min_y), std::abs(box.max_y - w.min_y),
                                 w.width(), w.height()}) +
                       radius;
  const double r = radius + grid.pixel_size() / 16 + scale * 0x1p-18;
  SiteShape shape;
  const double m = site.multiplicative, a = site.additive;
  if (ExactPoint(params, site)) {
    shape.per_fragment = true;
    shape.extent = r * std::numbers::sqrt2 * (1 + 0x1p-20);
    shape.area = 4 * r * r;
  } else if (PerFragment(params, site)) {
    shape.per_fragment = true;
    shape.extent = r;
    shape.area = (box.width() + 2 * r) * (box.height() + 2 * r);
  } else {
    const uint32_t needed = ConeSegments(r + params.eps, params.eps);
    shape.segments = SegmentBucket(needed);
    shape.overestimate = 1 / std::cos(std::numbers::pi / shape.segments);
    shape.extent = r * shape.overestimate * (1 + 0x1p-20);
    shape.excess = needed > kMaxConeSegments ? m * (shape.overestimate - 1) * shape.extent
                                             : m * params.eps;
    ForEachPiece(
        site.geometry, [&](Vec2) { shape.area += std::numbers::pi * r * r; },
        [&](Vec2 p, Vec2 q) { shape.area += 2 * r * Distance(p, q); });
  }
  shape.max_value = (m * shape.extent + a) * (1 + 0x1p-20);
  return shape;
}

absl::Status Rasterizer::Draw(const Grid& grid, const DrawParams& params, PixelRect scissor,
                              bool clear, const SlotTable& sites,
                              const std::vector<SiteDraw>& draws, RenderTarget& target,
                              uint32_t x0, uint32_t y0) {
  if (uint64_t{x0} + grid.width > target.width() || uint64_t{y0} + grid.height > target.height()) {
    return absl::InternalError("the grid does not fit in the render target");
  }
  if (scissor.empty()) return absl::OkStatus();
  struct Cone {
    float x, y, rho, m, a;
    uint32_t site;
  };
  struct Tent {
    float ax, ay, bx, by, r, m, a;
    uint32_t site;
  };
  struct Quad {
    float x0, y0, x1, y1, m, a, reach, ax, ay, bx, by;
    uint32_t site, first, count, side;
  };
  std::map<uint32_t, std::vector<Cone>> cones;  // by triangle count
  std::vector<Tent> tents;
  std::vector<Quad> quads;
  struct Square {
    float x, y, r, m, a;
    uint32_t site;
  };
  std::vector<Square> squares;
  std::vector<float> segments;  // x0, y0, x1, y1 per segment, for the quads
  const Vec2 origin{grid.window.min_x, grid.window.min_y};
  auto rel = [&](Vec2 p) { return p - origin; };
  for (const SiteDraw& d : draws) {
    const Site& site = *sites.get(d.slot);
    SiteShape shape = Shape(grid, params, site, d.radius);
    const float m = static_cast<float>(site.multiplicative);
    const float a = static_cast<float>(site.additive);
    const uint32_t id = d.slot + 1;
    if (ExactPoint(params, site)) {
      // Half side: the radius with its margins (the shape's extent is the corners' reach).
      const double half = shape.extent / (std::numbers::sqrt2 * (1 + 0x1p-20));
      Vec2 u = rel(std::get<PointSite>(site.geometry).p);
      squares.push_back({float(u.x), float(u.y), float(half), m, a, id});
      continue;
    }
    if (shape.per_fragment) {
      Window b = BoundingBox(site.geometry);
      const double r = shape.extent;
      uint32_t first = static_cast<uint32_t>(segments.size() / 4), count = 0;
      ForEachSegment(site.geometry, [&](Vec2 p, Vec2 q) {
        Vec2 u = rel(p), v = rel(q);
        segments.insert(segments.end(), {float(u.x), float(u.y), float(v.x), float(v.y)});
        ++count;
      });
      uint32_t side = 0;
      if (const auto* poly = std::get_if<PolygonSite>(&site.geometry)) {
        side = poly->side == Side::kOutside ? 1 : poly->side == Side::kInside ? 2 : 0;
      }
      Vec2 lo = rel({b.min_x - r, b.min_y - r}), hi = rel({b.max_x + r, b.max_y + r});
      const float* s0 = &segments[size_t{first} * 4];
      quads.push_back({float(lo.x), float(lo.y), float(hi.x), float(hi.y), m, a, float(r), s0[0],
                       s0[1], s0[2], s0[3], id, first, count, side});
      continue;
    }
    const float rho = static_cast<float>(shape.extent);
    ForEachPiece(
        site.geometry,
        [&](Vec2 p) {
          Vec2 u = rel(p);
          cones[shape.segments].push_back({float(u.x), float(u.y), rho, m, a, id});
        },
        [&](Vec2 p, Vec2 q) {
          Vec2 u = rel(p), v = rel(q);
          tents.push_back(
              {float(u.x), float(u.y), float(v.x), float(v.y), float(shape.extent), m, a, id});
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
  const float scale[2] = {static_cast<float>(2 / grid.window.width()),
                          static_cast<float>(2 / grid.window.height())};
  const float inv_depth = static_cast<float>(1 / params.depth_scale);
  auto use = [&](const Program& p) {
    glUseProgram(p.id);
    glUniform2f(p.u_scale, scale[0], scale[1]);
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
    glBindBuffer(GL_ARRAY_BUFFER, instances_);
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
  glBindVertexArray(vao_);
  for (GLuint location = 0; location < 5; ++location) glDisableVertexAttribArray(location);
  if (!cones.empty()) {
    use(cone_);
    for (const auto& [n, list] : cones) {
      bind(ConeBuffer(n), list.data(), list.size(), sizeof(Cone), {3, 2}, 1);
      glDrawArraysInstanced(GL_TRIANGLES, 0, static_cast<GLsizei>(n * 3),
                            static_cast<GLsizei>(list.size()));
    }
  }
  if (!tents.empty()) {
    use(tent_);
    bind(tent_mesh_, tents.data(), tents.size(), sizeof(Tent), {4, 3}, 1);
    glDrawArraysInstanced(GL_TRIANGLES, 0, 12, static_cast<GLsizei>(tents.size()));
  }
  if (!squares.empty()) {
    use(exact_point_);
    glUniform2f(exact_point_.u_pixel, static_cast<float>(grid.pixel_width()),
                static_cast<float>(grid.pixel_height()));
    glUniform2f(exact_point_.u_origin, static_cast<float>(x0), static_cast<float>(y0));
    bind(quad_, squares.data(), squares.size(), sizeof(Square), {3, 2}, 1);
    glDrawArraysInstanced(GL_TRIANGLES, 0, 6, static_cast<GLsizei>(squares.size()));
  }
  if (!quads.empty()) {
    use(exact_);
    glUniform2f(exact_.u_pixel, static_cast<float>(grid.pixel_width()),
                static_cast<float>(grid.pixel_height()));
    glUniform1f(exact_.u_margin, static_cast<float>(DrawMargin(grid)));
    glUniform2f(exact_.u_origin, static_cast<float>(x0), static_cast<float>(y0));
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, segments_);
    glBufferData(GL_SHADER_STORAGE_BUFFER, segments.size() * sizeof(float), segments.data(),
                 GL_STREAM_DRAW);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, segments_);
    bind(quad_, quads.data(), quads.size(), sizeof(Quad), {4, 3, 4}, 4);
    glDrawArraysInstanced(GL_TRIANGLES, 0, 6, static_cast<GLsizei>(quads.size()));
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

void ErrorTally::Live(const Site& site) {
  max_weight_ = std::max(max_weight_, site.multiplicative);
  const auto* poly = std::get_if<PolygonSite>(&site.geometry);
  if (std::isfinite(site.max_distance) || (poly && poly->side != Side::kBoth)) {
    limited_presence_ = true;
  }
  if (const auto* b = std::get_if<BezierSite>(&site.geometry)) {
    curve_slack_ = std::max(curve_slack_, b->tolerance * site.multiplicative);
  }
}

void ErrorTally::Drawn(const Grid& grid, const Site& site, const SiteShape& shape) {
  overestimate_ = std::max(overestimate_, shape.overestimate);
  excess_ = std::max(excess_, shape.excess);
  // How large the float coordinates of the drawn site get, relative to the window's min
  // corner: its geometry and the reach of its pieces.
  Window b = BoundingBox(site.geometry);
  double x = std::max(std::abs(b.min_x - grid.window.min_x), std::abs(b.max_x - grid.window.min_x));
  double y = std::max(std::abs(b.min_y - grid.window.min_y), std::abs(b.max_y - grid.window.min_y));
  coordinate_scale_ = std::max(coordinate_scale_, std::max({x, y, grid.window.width(),
                                                            grid.window.height()}) +
                                                      shape.extent);
}

ErrorModel ErrorTally::Model(const Grid& grid, const DrawParams& params) const {
  // Vertices snap to 1/256 pixel (GL_SUBPIXEL_BITS = 8 on llvmpipe and NVIDIA), which moves a
  // cone's surface by at most 1/256 pixel diagonal, as its slope is at most k ~ 1: we allow
  // 1/64. Float interpolation and depth storage err by a few ulps of the depth range and of D.
  // Positions are floats relative to the window's min corner, so distances err by a few ulps
  // of the largest coordinate or reach drawn. A weight scales all of it.
  ErrorModel error;
  error.diagram = params.diagram;
  error.overestimate = overestimate_;
  error.max_excess =
      params.mode == RenderMode::kExact ? 0 : std::max(params.eps * max_weight_, excess_);
  error.absolute_slack = (grid.pixel_diagonal() / 64 + coordinate_scale_ * 0x1p-18) * max_weight_;
  error.relative_slack = 0x1p-18;
  error.lipschitz = max_weight_;
  error.curve = curve_slack_;
  error.limited_presence = limited_presence_;
  return error;
}

absl::StatusOr<std::shared_ptr<const Frame>> Rasterizer::Render(const Grid& grid, double eps,
                                                                uint64_t version,
                                                                const SiteTable& sites,
                                                                RenderStats* stats,
                                                                RenderMode mode,
                                                                Diagram diagram) {
  auto scene = SceneRaster::Create(grid, eps, mode, diagram);
  if (!scene.ok()) return scene.status();
  return (*scene)->Apply(*this, SiteSnapshot::Of(version, sites), stats);
}

}  // namespace gvd

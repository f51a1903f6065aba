#include "render/gl/rasterizer.h"

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include <glm/gtc/type_ptr.hpp>
#include <glm/vec4.hpp>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "render/plan/coverage.h"
#include "render/kernel/exact2.h"
#include "render/plan/distance_mesh.h"
#include "render/scene/cpu_pool.h"
#include "render/gl/shaders.h"

namespace gvd {
namespace {

// Every program (gl/shaders/*.glsl) works in scene units relative to the window's min
// corner, with depth = value / depth_scale; glClipControl(ZERO_TO_ONE) keeps it unchanged
// into the depth buffer, with no [-1, 1] remapping to cost precision.

absl::Status GlError(const char* what) {
  GLenum e = glGetError();
  if (e == GL_NO_ERROR) return absl::OkStatus();
  return absl::InternalError(absl::StrCat(what, ": GL error 0x", absl::Hex(e)));
}

absl::StatusOr<GLuint> Compile(GLenum kind, const char* text) {
  // The one file shaders share, put in place of its #include line.
  std::string source = text;
  const std::string include = "#include \"segments.glsl\"\n";
  if (size_t at = source.find(include); at != std::string::npos) {
    source.replace(at, include.size(), shaders::kSegments);
  }
  const char* sources[] = {source.c_str()};
  GLuint shader = glCreateShader(kind);
  glShaderSource(shader, 1, sources, nullptr);
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

absl::StatusOr<std::unique_ptr<Rasterizer>> Rasterizer::Create(const DeviceInfo& device) {
  std::unique_ptr<Rasterizer> r(new Rasterizer());
  r->software_ = device.software;
  r->native_scan_ = device.software;
  for (auto [program, vertex, fragment] :
       {std::tuple{&r->cone_, shaders::kConeVert, shaders::kIdFrag},
        std::tuple{&r->tent_, shaders::kTentVert, shaders::kIdFrag},
        std::tuple{&r->exact_, shaders::kExactVert, shaders::kExactFrag},
        std::tuple{&r->exact_point_, shaders::kExactPointVert, shaders::kExactPointFrag}}) {
    auto linked = Link(vertex, fragment);
    if (!linked.ok()) return linked.status();
    *program = *linked;
  }
  {
    auto resolve = Link(shaders::kResolveVert, shaders::kResolveFrag);
    if (!resolve.ok()) return resolve.status();
    r->resolve_ = *resolve;
    auto compute = Compile(GL_COMPUTE_SHADER, shaders::kNearestComp);
    if (!compute.ok()) return compute.status();
    r->nearest_ = glCreateProgram();
    glAttachShader(r->nearest_, *compute);
    glLinkProgram(r->nearest_);
    glDeleteShader(*compute);
    GLint ok = 0;
    glGetProgramiv(r->nearest_, GL_LINK_STATUS, &ok);
    if (!ok) {
      char log[2048] = {};
      glGetProgramInfoLog(r->nearest_, sizeof log, nullptr, log);
      return absl::InternalError(absl::StrCat("compute shader link failed: ", log));
    }
    glGenBuffers(7, r->compute_buffers_);
    GLint64 max_block = 0;
    glGetInteger64v(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &max_block);
    r->max_storage_block_ = max_block;
  }
  glGenVertexArrays(1, &r->vao_);
  glGenBuffers(1, &r->instances_);
  glGenBuffers(1, &r->segments_);
  glGenBuffers(1, &r->indirect_);
  // Two triangles spanning [0, 1]^2.
  const float quad[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 0, 0, 1, 1, 0, 0, 1, 0};
  glGenBuffers(1, &r->quad_);
  glBindBuffer(GL_ARRAY_BUFFER, r->quad_);
  glBufferData(GL_ARRAY_BUFFER, sizeof quad, quad, GL_STATIC_DRAW);
  // Half a tent, (u, v, unused): the segment at v = 0, the far side at v = 1; and a strip
  // beyond the segment, v = -1 (tent.vert).
  const float tent[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 0, 0, 1, 1, 0, 0, 1, 0,
                        0, -1, 0, 1, -1, 0, 1, 0, 0, 0, -1, 0, 1, 0, 0, 0, 0, 0};
  glGenBuffers(1, &r->tent_mesh_);
  glBindBuffer(GL_ARRAY_BUFFER, r->tent_mesh_);
  glBufferData(GL_ARRAY_BUFFER, sizeof tent, tent, GL_STATIC_DRAW);
  if (auto s = GlError("creating the rasterizer"); !s.ok()) return s;
  return r;
}

Rasterizer::~Rasterizer() {
  for (auto& [n, buffer] : cones_) glDeleteBuffers(1, &buffer);
  for (unsigned b : {quad_, tent_mesh_, instances_, segments_, indirect_}) glDeleteBuffers(1, &b);
  glDeleteVertexArrays(1, &vao_);
  for (const Program* p : {&cone_, &tent_, &exact_, &exact_point_, &resolve_}) {
    glDeleteProgram(p->id);
  }
  glDeleteProgram(nearest_);
  glDeleteBuffers(7, compute_buffers_);
}

unsigned Rasterizer::ConeBuffer(uint32_t segments) {
  auto it = cones_.find(segments);
  if (it == cones_.end()) {
    // Two turns, so that any range of up to `segments` triangles is contiguous (FanTriangles).
    ConeMesh mesh = BuildUnitCone(segments);
    const size_t turn = mesh.vertices.size();
    mesh.vertices.resize(2 * turn);
    std::copy_n(mesh.vertices.begin(), turn, mesh.vertices.begin() + turn);
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

// A site drawn per fragment as exact.vert and nearest.comp take it: its first segment, (m,
// a, reach) and (id, index of the first segment, segment count, side), its segments appended
// to `segments`, all relative to `origin`.
struct PerFragmentSite {
  glm::vec4 first;
  glm::vec3 weight;
  glm::uvec4 info;
};
PerFragmentSite PerFragmentOf(const Site& site, uint32_t id, double reach, Vec2 origin,
                              std::vector<glm::vec4>* segments) {
  auto rel = [&](Vec2 p) { return glm::vec2(p - origin); };
  uint32_t first = static_cast<uint32_t>(segments->size()), count = 0;
  ForEachSegment(site.geometry, [&](Vec2 p, Vec2 q) {
    segments->emplace_back(rel(p), rel(q));
    ++count;
  });
  uint32_t side = 0;
  if (const auto* poly = std::get_if<PolygonSite>(&site.geometry)) {
    side = poly->side == Side::kOutside ? 1 : poly->side == Side::kInside ? 2 : 0;
  }
  return {(*segments)[first],
          glm::vec3(site.multiplicative, site.additive, reach),
          glm::uvec4(id, first, count, side)};
}

// The area of the convex polygon within `clip` (Sutherland-Hodgman, one side at a time).
double AreaWithin(const Window& clip, std::vector<Vec2> polygon) {
  std::vector<Vec2> next;
  // Keeps the part where s * (coordinate axis of p - bound) <= 0.
  auto cut = [&](int axis, double bound, double s) {
    next.clear();
    for (size_t i = 0; i < polygon.size(); ++i) {
      const Vec2 p = polygon[i], q = polygon[(i + 1) % polygon.size()];
      const double fp = s * (p[axis] - bound), fq = s * (q[axis] - bound);
      if (fp <= 0) next.push_back(p);
      if ((fp < 0) != (fq < 0) && fp != fq) next.push_back(p + (q - p) * (fp / (fp - fq)));
    }
    polygon.swap(next);
  };
  cut(0, clip.min_x, -1);
  cut(0, clip.max_x, 1);
  cut(1, clip.min_y, -1);
  cut(1, clip.max_y, 1);
  double twice = 0;
  for (size_t i = 0; i < polygon.size(); ++i) {
    const Vec2 p = polygon[i], q = polygon[(i + 1) % polygon.size()];
    twice += p.x * q.y - q.x * p.y;
  }
  return std::abs(twice) / 2;
}

// The area of the box within `lo`..`hi` that lies in `clip`.
double AreaWithin(const Window& clip, Vec2 lo, Vec2 hi) {
  return std::max(0.0, std::min(hi.x, clip.max_x) - std::max(lo.x, clip.min_x)) *
         std::max(0.0, std::min(hi.y, clip.max_y) - std::max(lo.y, clip.min_y));
}

// How the fan of a site drawn with `segments` triangles a turn is drawn over the directions
// [from, to]: the whole cone, or a range of a finer one (eight times the triangles a turn,
// so that the triangle of margin FanTriangles adds on each side costs little area). A finer
// fan with the same extent covers at least the same radius, with a smaller overestimate.
struct FanDraw {
  uint32_t segments = 0;
  FanRange range;
  bool whole() const { return range.count == segments; }
};
FanDraw FanOf(uint32_t segments, double from, double to) {
  FanDraw fan{segments, FanTriangles(from, to, segments)};
  if (fan.whole()) return fan;
  const uint32_t fine = SegmentBucket(std::min(8 * segments, kMaxConeSegments));
  return {fine, FanTriangles(from, to, fine)};
}

// ForEachPiece of a site drawn as `shape`, with each piece's extent and clip: its own from
// draw.pieces where the coverage gave them (pieces with none are left out), else the site's;
// and each half-tent's part of its edge, g(extent, clip, a, b, from, to), from and to as
// fractions of ab (0 and 1 where the coverage gave none).
template <class F, class G>
void ForEachPieceDrawn(const SiteShape& shape, const SiteDraw& draw, const Geometry& geometry,
                       F&& f, G&& g) {
  size_t k = 0;
  const PieceDraw* p = nullptr;
  auto piece = [&](double* extent, PixelRect* clip) {
    *extent = shape.extent;
    *clip = draw.clip;
    p = nullptr;
    if (k >= draw.pieces.size()) return true;
    p = &draw.pieces[k++];
    if (p->radius < 0) return false;
    *extent = std::min(shape.extent, (p->radius + shape.pad) * shape.overestimate * (1 + 0x1p-20));
    *clip = p->clip;
    return true;
  };
  double e;
  PixelRect clip;
  ForEachPiece(
      geometry,
      [&](Vec2 q, double from, double to) {
        if (piece(&e, &clip)) f(e, clip, q, from, to);
      },
      [&](Vec2 a, Vec2 b) {
        if (!piece(&e, &clip)) return;
        // The part of the edge it needs, as fractions of ab, a pad beyond it (as its extent).
        double from = 0, to = 1;
        if (p != nullptr && p->from <= p->to) {
          const double length = Distance(a, b);
          from = std::max(0.0, (p->from - shape.pad) / length);
          to = std::min(1.0, (p->to + shape.pad) / length);
        }
        g(e, clip, a, b, from, to);
      });
}

// nearest.comp's Site, std430: a site scanned per fragment.
struct ComputeSite {
  glm::vec4 first;   // its first segment
  glm::vec4 weight;  // (m, a, reach, unused)
  glm::uvec4 info;   // (slot + 1, first segment, segment count, side: 0 both, 1 outside, 2 inside)
};
static_assert(sizeof(ComputeSite) == 12 * 4);

// What ScanTile reads.
struct ScanInput {
  const Rasterizer::TileLists& lists;
  const std::vector<ComputeSite>& sites;
  const std::vector<glm::vec4>& segments;
  float pw, ph;  // a pixel's size
  float margin;  // DrawMargin
};

constexpr uint32_t kScanTile = Rasterizer::kComputeTile;
constexpr uint32_t kScanPixels = kScanTile * kScanTile;

// nearest.comp for one tile (t, at pixel x0, y0), as native code: each pixel centre gets the
// least value among the tile's candidates present there, ties to the lower id (plain points
// compared by squared distance), in float from the same inputs; id 0 and +infinity where no
// candidate is present. Each candidate is taken over the whole tile at once, so that the
// pixels' loops vectorize. (Compiled for AVX2 as well, chosen at run time, it was no faster
// on the build machine: 1,000 cubic Beziers at 1024x1024 took 49-52 ms either way.)
void ScanTile(const ScanInput& in, size_t t, uint32_t x0, uint32_t y0, float* best,
              uint32_t* id) {
  constexpr uint32_t kTile = kScanTile, kPixels = kScanPixels;
  alignas(32) float px[kPixels], py[kPixels], xs[kTile], ys[kTile], d2[kPixels];
  alignas(32) bool inside[kPixels];
  const Rasterizer::TileLists& lists = in.lists;
  for (uint32_t i = 0; i < kTile; ++i) {
    xs[i] = (static_cast<float>(x0 + i) + 0.5f) * in.pw;
    ys[i] = (static_cast<float>(y0 + i) + 0.5f) * in.ph;
  }
  std::fill(best, best + kPixels, INFINITY);
  std::fill(id, id + kPixels, 0u);
  const uint32_t* at = &lists.offsets[3 * t];  // where each list of the tile starts
  const uint32_t* next = at + 3;               // and ends
  // Plain points, by squared distance, row by row.
  for (uint32_t k = at[0]; k < next[0]; ++k) {
    const Rasterizer::Point q = lists.points[k];
    for (uint32_t j = 0; j < kTile; ++j) {
      const float dy = ys[j] - q.y, dy2 = dy * dy;
      float* row = best + j * kTile;
      uint32_t* row_id = id + j * kTile;
      for (uint32_t i = 0; i < kTile; ++i) {
        const float dx = xs[i] - q.x;
        const float dd = dx * dx + dy2;
        const bool better = dd < row[i] || (dd == row[i] && q.id < row_id[i]);
        row[i] = better ? dd : row[i];
        row_id[i] = better ? q.id : row_id[i];
      }
    }
  }
  for (uint32_t i = 0; i < kPixels; ++i) best[i] = std::sqrt(best[i]);
  if (at[1] == next[1] && at[2] == next[2]) return;
  // The other sites compare values.
  for (uint32_t j = 0; j < kTile; ++j) {
    for (uint32_t i = 0; i < kTile; ++i) {
      px[j * kTile + i] = xs[i];
      py[j * kTile + i] = ys[j];
    }
  }
  // The least distance from each pixel to the segment (a, b) into d2, squared, and the
  // even-odd crossings of a ray towards +x into `inside` (when `side`).
  auto visit = [&](const glm::vec4& s, bool side) {
    const float ax = s.x, ay = s.y, abx = s.z - s.x, aby = s.w - s.y;
    const float len2 = abx * abx + aby * aby;
    const float inv = len2 > 0 ? 1 / len2 : 0;
    for (uint32_t i = 0; i < kPixels; ++i) {
      const float apx = px[i] - ax, apy = py[i] - ay;
      const float u = std::clamp((apx * abx + apy * aby) * inv, 0.0f, 1.0f);
      const float dx = apx - u * abx, dy = apy - u * aby;
      d2[i] = std::min(d2[i], dx * dx + dy * dy);
    }
    if (!side) return;
    for (uint32_t i = 0; i < kPixels; ++i) {
      if ((s.y > py[i]) != (s.w > py[i]) &&
          px[i] < s.x + (py[i] - s.y) / (s.w - s.y) * (s.z - s.x)) {
        inside[i] = !inside[i];
      }
    }
  };
  // A site's value from the least distance in d2, as nearest.comp takes it.
  auto take = [&](const ComputeSite& s, bool side) {
    const float m = s.weight.x, a = s.weight.y, reach = s.weight.z;
    const uint32_t site = s.info.x;
    const bool want_inside = s.info.w == 2;
    for (uint32_t i = 0; i < kPixels; ++i) {
      const float d = std::sqrt(d2[i]);
      const float value = m * d + a;
      bool present = d <= reach;
      if (side) present = present && (d <= in.margin || inside[i] == want_inside);
      const bool better = value < best[i] || (value == best[i] && site < id[i]);
      best[i] = present && better ? value : best[i];
      id[i] = present && better ? site : id[i];
    }
  };
  // Sites scanned whole.
  for (uint32_t k = at[1]; k < next[1]; ++k) {
    const ComputeSite& s = in.sites[lists.sites[k]];
    const bool side = s.info.w != 0;
    std::fill(d2, d2 + kPixels, INFINITY);
    std::fill(inside, inside + kPixels, false);
    for (uint32_t g = s.info.y; g < s.info.y + s.info.z; ++g) visit(in.segments[g], side);
    take(s, side);
  }
  // Single segments, a site's next to each other: the least over them, then its value.
  for (uint32_t k = at[2]; k < next[2];) {
    const uint32_t site = lists.segments[k].site;
    const ComputeSite& s = in.sites[site];
    std::fill(d2, d2 + kPixels, INFINITY);
    for (; k < next[2] && lists.segments[k].site == site; ++k) {
      visit(in.segments[s.info.y + lists.segments[k].index], false);
    }
    take(s, false);
  }
}

// nearest.comp as native code on the CPU pool, tile by tile (ScanTile): the ids and values
// the shader would write, `none` where no candidate is present.
void ScanTiles(const Grid& grid, const Rasterizer::TileLists& lists,
               const std::vector<ComputeSite>& sites, const std::vector<glm::vec4>& segments,
               float none, float margin, std::vector<uint32_t>* ids, std::vector<float>* values) {
  const uint32_t tiles_x = (grid.width + kScanTile - 1) / kScanTile;
  const uint32_t tiles_y = (grid.height + kScanTile - 1) / kScanTile;
  const ScanInput in{lists, sites, segments, static_cast<float>(grid.pixel_width()),
                     static_cast<float>(grid.pixel_height()), margin};
  ids->resize(grid.pixel_count());
  values->resize(grid.pixel_count());
  ParallelFor(tiles_y, 1, [&](size_t begin, size_t end) {
    alignas(32) float best[kScanPixels];
    alignas(32) uint32_t id[kScanPixels];
    for (size_t ty = begin; ty < end; ++ty) {
      const uint32_t y0 = static_cast<uint32_t>(ty) * kScanTile;
      for (uint32_t tx = 0; tx < tiles_x; ++tx) {
        const uint32_t x0 = tx * kScanTile;
        ScanTile(in, ty * tiles_x + tx, x0, y0, best, id);
        for (uint32_t y = y0; y < std::min(y0 + kScanTile, grid.height); ++y) {
          for (uint32_t x = x0; x < std::min(x0 + kScanTile, grid.width); ++x) {
            const size_t i = size_t{y} * grid.width + x;
            const uint32_t k = (y - y0) * kScanTile + (x - x0);
            (*ids)[i] = id[k];
            (*values)[i] = id[k] == 0 ? none : best[k];
          }
        }
      }
    }
  });
}

}  // namespace

SiteShape Rasterizer::Shape(const Grid& grid, const DrawParams& params, const Site& site,
                            const SiteDraw& draw) const {
  const double radius = draw.radius;
  const Window clip = grid.Area(draw.clip);
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
  SiteShape shape;
  shape.pad = grid.pixel_size() / 16 + scale * 0x1p-18;
  const double r = radius + shape.pad;
  const double m = site.multiplicative, a = site.additive;
  // Areas: each piece's, or its box's within the clip where that is less.
  if (ExactPoint(params, site)) {
    shape.per_fragment = true;
    shape.extent = r * std::numbers::sqrt2 * (1 + 0x1p-20);
    shape.area = AreaWithin(clip, {box.min_x - r, box.min_y - r}, {box.max_x + r, box.max_y + r});
  } else if (PerFragment(params, site)) {
    shape.per_fragment = true;
    shape.extent = r;
    shape.area = AreaWithin(clip, {box.min_x - r, box.min_y - r}, {box.max_x + r, box.max_y + r});
  } else {
    const uint32_t needed = ConeSegments(r + params.eps, params.eps);
    shape.segments = SegmentBucket(needed);
    shape.overestimate = 1 / std::cos(std::numbers::pi / shape.segments);
    shape.extent = r * shape.overestimate * (1 + 0x1p-20);
    shape.excess = needed > kMaxConeSegments ? m * (shape.overestimate - 1) * shape.extent
                                             : m * params.eps;
    ForEachPieceDrawn(shape, draw, site.geometry, [&](double e, PixelRect piece_clip, Vec2 p,
                                                      double from, double to) {
      const FanDraw fan = FanOf(shape.segments, from, to);
      const Window c = grid.Area(piece_clip);
      if (fan.whole()) {  // a point's cone: its box's part within the clip, at most its own
        shape.area += std::min(std::numbers::pi * e * e,
                               AreaWithin(c, {p.x - e, p.y - e}, {p.x + e, p.y + e}));
        return;
      }
      std::vector<Vec2> wedge = {p};
      for (uint32_t k = 0; k <= fan.range.count; ++k) {
        const double t = 2 * std::numbers::pi * (fan.range.first + k) / fan.segments;
        wedge.push_back(p + e * Vec2{std::cos(t), std::sin(t)});
      }
      shape.area += AreaWithin(c, std::move(wedge));
    }, [&](double e, PixelRect piece_clip, Vec2 p, Vec2 q, double from, double to) {
      const Vec2 n = Vec2{p.y - q.y, q.x - p.x} * (e / Distance(p, q));  // to the left
      const Vec2 a = p + from * (q - p), b = p + to * (q - p);
      shape.area += AreaWithin(grid.Area(piece_clip), {a, b, b + n, a + n});
    });
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
    SiteShape shape = Shape(grid, params, site, d);
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
    glUseProgram(p.id);
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
      glBindBuffer(GL_DRAW_INDIRECT_BUFFER, indirect_);
      glBufferData(GL_DRAW_INDIRECT_BUFFER, commands.size() * sizeof(Command), commands.data(),
                   GL_STREAM_DRAW);
      glMultiDrawArraysIndirect(GL_TRIANGLES, nullptr, static_cast<GLsizei>(commands.size()), 0);
      glBindBuffer(GL_DRAW_INDIRECT_BUFFER, 0);
    }
  }
  if (!tents.empty()) {
    use(tent_);
    glUniform1f(glGetUniformLocation(tent_.id, "u_overhang"),
                static_cast<float>(grid.pixel_size() / 64));
    bind(tent_mesh_, tents.data(), tents.size(), sizeof(Tent), {4, 3, 4, 2}, 1);
    glDrawArraysInstanced(GL_TRIANGLES, 0, 12, static_cast<GLsizei>(tents.size()));
  }
  for (GLenum plane = 0; plane < 4; ++plane) glDisable(GL_CLIP_DISTANCE0 + plane);
  if (!squares.empty()) {
    use(exact_point_);
    glUniform2fv(exact_point_.u_pixel, 1, glm::value_ptr(pixel));
    glUniform2fv(exact_point_.u_origin, 1, glm::value_ptr(target_origin));
    bind(quad_, squares.data(), squares.size(), sizeof(Square), {4, 2, 2}, 1);
    glDrawArraysInstanced(GL_TRIANGLES, 0, 6, static_cast<GLsizei>(squares.size()));
  }
  if (!quads.empty()) {
    use(exact_);
    glUniform2fv(exact_.u_pixel, 1, glm::value_ptr(pixel));
    glUniform1f(exact_.u_margin, static_cast<float>(DrawMargin(grid)));
    glUniform2fv(exact_.u_origin, 1, glm::value_ptr(target_origin));
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, segments_);
    glBufferData(GL_SHADER_STORAGE_BUFFER, segments.size() * sizeof(glm::vec4), segments.data(),
                 GL_STREAM_DRAW);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, segments_);
    bind(quad_, quads.data(), quads.size(), sizeof(Quad), {4, 3, 4}, 4);
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
  const uint32_t tiles_x = (grid.width + kComputeTile - 1) / kComputeTile;
  const uint32_t tiles_y = (grid.height + kComputeTile - 1) / kComputeTile;
  if (grid.width > target.width() || grid.height > target.height() ||
      lists.offsets.size() != 3 * (size_t{tiles_x} * tiles_y + 1)) {
    return absl::InternalError("the grid or its tiles do not match the render target");
  }
  auto upload = [](GLuint buffer, GLuint binding, const void* data, size_t bytes) {
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, buffer);
    glBufferData(GL_SHADER_STORAGE_BUFFER, static_cast<GLsizeiptr>(bytes), data, GL_STREAM_DRAW);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding, buffer);
  };
  const size_t pixels = grid.pixel_count();
  std::vector<ComputeSite> records;
  records.reserve(draws.size());
  std::vector<glm::vec4> segments;
  const Vec2 origin{grid.window.min_x, grid.window.min_y};
  for (const SiteDraw& d : draws) {
    // Plain points are scanned from the lists' own points: their records are never read.
    if (!std::isnan(sites.point(d.slot).x)) {
      records.emplace_back();
      continue;
    }
    const Site& site = *sites.get(d.slot);
    const SiteShape shape = Shape(grid, params, site, d);
    PerFragmentSite f = PerFragmentOf(site, d.slot + 1, shape.extent, origin, &segments);
    records.push_back({f.first, glm::vec4(f.weight, 0), f.info});
  }
  // What the GL's storage buffers must hold: the resolve's pixels always, the lists too for
  // the shader.
  std::vector<std::pair<size_t, const char*>> buffers = {
      {pixels * sizeof(uint32_t), "the pixels' ids"}};
  if (!native_scan_) {
    buffers.insert(buffers.end(),
                   {{segments.size() * sizeof(glm::vec4), "the segments"},
                    {records.size() * sizeof(ComputeSite), "the sites"},
                    {lists.points.size() * sizeof(Point), "the tiles' points"},
                    {lists.sites.size() * sizeof(uint32_t), "the tiles' sites"},
                    {lists.segments.size() * sizeof(Segment), "the tiles' segments"}});
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
    // would have written it.
    ScanTiles(grid, lists, records, segments, static_cast<float>(params.depth_scale),
              static_cast<float>(DrawMargin(grid)), ids, distances);
    upload(compute_buffers_[3], 4, ids->data(), pixels * sizeof(uint32_t));
    upload(compute_buffers_[4], 5, distances->data(), pixels * sizeof(float));
    return Resolve(grid, params, target);
  }
  if (segments.empty()) segments.emplace_back();  // no buffer may be empty
  if (records.empty()) records.emplace_back();
  static_assert(sizeof(Point) == 4 * 4 && sizeof(Segment) == 2 * 4);
  const uint32_t no_site = 0;
  const Point no_point{};
  const Segment no_segment{};
  upload(segments_, 0, segments.data(), segments.size() * sizeof(glm::vec4));
  upload(compute_buffers_[0], 1, records.data(), records.size() * sizeof(ComputeSite));
  upload(compute_buffers_[1], 2, lists.offsets.data(), lists.offsets.size() * sizeof(uint32_t));
  upload(compute_buffers_[2], 3, lists.sites.empty() ? &no_site : lists.sites.data(),
         std::max<size_t>(lists.sites.size(), 1) * sizeof(uint32_t));
  upload(compute_buffers_[5], 6, lists.points.empty() ? &no_point : lists.points.data(),
         std::max<size_t>(lists.points.size(), 1) * sizeof(Point));
  upload(compute_buffers_[6], 7, lists.segments.empty() ? &no_segment : lists.segments.data(),
         std::max<size_t>(lists.segments.size(), 1) * sizeof(Segment));
  upload(compute_buffers_[3], 4, nullptr, pixels * sizeof(uint32_t));
  upload(compute_buffers_[4], 5, nullptr, pixels * sizeof(float));
  glUseProgram(nearest_);
  glUniform2ui(glGetUniformLocation(nearest_, "u_size"), grid.width, grid.height);
  glUniform2f(glGetUniformLocation(nearest_, "u_pixel"), static_cast<float>(grid.pixel_width()),
              static_cast<float>(grid.pixel_height()));
  glUniform1f(glGetUniformLocation(nearest_, "u_margin"), static_cast<float>(DrawMargin(grid)));
  glUniform1f(glGetUniformLocation(nearest_, "u_none"), static_cast<float>(params.depth_scale));
  glDispatchCompute(tiles_x, tiles_y, 1);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
  // The frame's copy, then the target's: a triangle over the grid writes each pixel's id and
  // depth from the same buffers.
  ids->resize(pixels);
  distances->resize(pixels);
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, compute_buffers_[3]);
  glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, pixels * sizeof(uint32_t), ids->data());
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, compute_buffers_[4]);
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
  glUseProgram(resolve_.id);
  glUniform1ui(glGetUniformLocation(resolve_.id, "u_width"), grid.width);
  glUniform1f(resolve_.u_inv_depth, static_cast<float>(1 / params.depth_scale));
  glBindVertexArray(vao_);
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

}  // namespace gvd

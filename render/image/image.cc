#include "render/image/image.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <unordered_map>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "render/image/codec.h"
#include "render/kernel/exact2.h"
#include "render/kernel/exact3.h"

namespace gvd {
namespace {

uint64_t Fnv1a(const std::string& s, uint64_t h = 1469598103934665603ull) {
  for (unsigned char c : s) h = (h ^ c) * 1099511628211ull;
  return h;
}

// The site (slot + 1) shown at pixel (i, j) and its value there, or id 0. A site is
// present a little beyond its max_distance or side (DrawMargin), where it is no candidate:
// there the frame's answer at the centre (Frame::Nearest) says who is, if anyone, made
// exact from the frame's snapshot in a NEAREST diagram (SiteSnapshot::Improve).
struct ShownSite {
  uint32_t id = 0;
  double value = 0;
};
ShownSite Shown(const Frame& f, uint32_t i, uint32_t j, std::vector<uint32_t>* scratch) {
  const uint32_t id = f.id_at(i, j);
  if (id == 0) return {};
  if (!f.error().limited_presence) return {id, f.distance_at(i, j)};
  const Vec2 centre = f.grid().Center(i, j);
  if (std::isfinite(SiteValue(centre, *f.sites().get(id - 1)))) return {id, f.distance_at(i, j)};
  const std::optional<NearestAnswer> n = f.Nearest(centre);
  if (!n || !n->found) return {};
  uint32_t best = n->site_index;
  double value = n->distance;
  if (f.error().diagram == Diagram::kNearest) f.snapshot().Improve(centre, &best, &value, scratch);
  return {best + 1, value};
}

// Plots segment ab (scene units) over an RGB image of the rect, row 0 at the top, in `colour`,
// `thick` pixels wide (a point as a dot of 3 pixels or `thick`, whichever is more).
void DrawSegment(const Grid& g, const PixelRect& rect, Vec2 a, Vec2 b, const uint8_t colour[3],
                 int thick, std::vector<uint8_t>* rgb) {
  const uint32_t w = rect.width(), h = rect.height();
  auto plot = [&](double x, double y) {  // continuous pixel coordinates
    long i = std::lround(std::floor(x)) - rect.x0, j = std::lround(std::floor(y)) - rect.y0;
    if (i < 0 || j < 0 || i >= long(w) || j >= long(h)) return;
    size_t at = (size_t(h - 1 - j) * w + i) * 3;
    for (int c = 0; c < 3; ++c) (*rgb)[at + c] = colour[c];
  };
  Vec2 pa = g.ToPixel(a), pb = g.ToPixel(b);
  double len = Distance(pa, pb);
  const int r = len == 0 ? std::max(1, thick / 2) : thick / 2;
  auto dot = [&](Vec2 p) {
    for (int dx = -r; dx <= r; ++dx) {
      for (int dy = -r; dy <= r; ++dy) plot(p.x + dx, p.y + dy);
    }
  };
  if (len == 0) {
    dot(pa);
    return;
  }
  // Clip the walk to the image (segments may reach far outside it).
  double steps = std::min(len * 2, 4.0 * (g.width + g.height) + 8);
  for (double k = 0; k <= steps; ++k) dot(pa + (k / steps) * (pb - pa));
}

// Draws the sites' segments (and points, as 3x3 dots) in white.
void DrawSites(const Frame& f, const PixelRect& rect, std::vector<uint8_t>* rgb) {
  static constexpr uint8_t kWhite[3] = {255, 255, 255};
  for (uint32_t s = 0; s < f.sites().size(); ++s) {
    const Site* site = f.sites().get(s);
    if (site == nullptr) continue;
    ForEachSegment(site->geometry, [&](Vec2 a, Vec2 b) {
      DrawSegment(f.grid(), rect, a, b, kWhite, 1, rgb);
    });
  }
}

}  // namespace

void SiteColour(const std::string& id, uint32_t feature, uint8_t rgb[3]) {
  uint64_t h = Fnv1a(id);
  h = (h ^ feature) * 1099511628211ull;
  h ^= h >> 29;
  // Hue from the hash, high saturation and value: distinct from black and white.
  double hue = (h % 3600) / 3600.0 * 6, sat = 0.45 + (h >> 12) % 50 / 100.0,
         val = 0.7 + (h >> 20) % 30 / 100.0;
  int sector = static_cast<int>(hue) % 6;
  double frac = hue - std::floor(hue);
  double p = val * (1 - sat), q = val * (1 - sat * frac), t = val * (1 - sat * (1 - frac));
  double r, gr, b;
  switch (sector) {
    case 0: r = val, gr = t, b = p; break;
    case 1: r = q, gr = val, b = p; break;
    case 2: r = p, gr = val, b = t; break;
    case 3: r = p, gr = q, b = val; break;
    case 4: r = t, gr = p, b = val; break;
    default: r = val, gr = p, b = q; break;
  }
  rgb[0] = static_cast<uint8_t>(r * 255);
  rgb[1] = static_cast<uint8_t>(gr * 255);
  rgb[2] = static_cast<uint8_t>(b * 255);
}

namespace {

// What an image's pixel (x, y) of a w x h image shows, y = 0 its bottom row: its site (slot
// + 1, or 0) and value; the id of a site; the feature of a site nearest to a pixel, as a
// number (kFeatures).
struct PixelSource {
  uint32_t width = 0, height = 0;
  std::function<ShownSite(uint32_t x, uint32_t y)> shown;
  std::function<const std::string&(uint32_t id)> site_id;
  std::function<uint32_t(uint32_t x, uint32_t y, uint32_t id)> feature;
};

// An image being made: its pixels (one of the three buffers, rows top first) and how they are
// written.
struct Raster {
  RasterView spec;
  std::vector<uint8_t> rgb;
  std::vector<uint16_t> grey;
  std::vector<float> depth;
};

// The layer of the options, of the source's pixels.
absl::Status Fill(const PixelSource& src, const ImageOptions& o, Raster* r, EncodedImage* out) {
  const uint32_t w = src.width, h = src.height;
  out->width = w;
  out->height = h;
  const bool png = o.format == ImageFormat::kPng;
  auto row = [&](uint32_t y) { return size_t(h - 1 - y) * w; };  // row 0 at the top
  if (o.layer == ImageLayer::kDistance) {
    double max_value = 0;
    for (uint32_t y = 0; y < h; ++y) {
      for (uint32_t x = 0; x < w; ++x) {
        if (ShownSite s = src.shown(x, y); s.id) max_value = std::max(max_value, s.value);
      }
    }
    if (png) {
      r->grey.resize(size_t{w} * h);
      r->spec = {.width = w, .height = h, .channels = 1, .type = "uint16"};
    } else {
      r->depth.resize(size_t{w} * h);
      r->spec = {.width = w, .height = h, .channels = 1, .type = "float", .channel_names = {"Z"}};
    }
    for (uint32_t y = 0; y < h; ++y) {
      for (uint32_t x = 0; x < w; ++x) {
        const size_t at = row(y) + x;
        const ShownSite s = src.shown(x, y);
        const bool shown = s.id != 0;
        const double v = s.value;
        if (png) {
          r->grey[at] = shown && max_value > 0
                            ? static_cast<uint16_t>(std::lround(std::min(v / max_value, 1.0) * 65535))
                            : 0;
        } else {
          r->depth[at] = shown ? static_cast<float>(v) : INFINITY;
        }
      }
    }
    r->spec.float_attributes = {{"gvd:max_distance", static_cast<float>(max_value)}};
    return absl::OkStatus();
  }
  if (!png) return absl::InvalidArgumentError("format EXR holds the DISTANCE layer only");
  r->rgb.assign(size_t{w} * h * 3, 0);
  r->spec = {.width = w, .height = h, .channels = 3, .type = "uint8"};
  std::unordered_map<uint32_t, uint32_t> index;  // kSiteIndex: slot + 1 -> number written
  for (uint32_t y = 0; y < h; ++y) {
    for (uint32_t x = 0; x < w; ++x) {
      const uint32_t id = src.shown(x, y).id;
      if (id == 0) continue;
      uint8_t* px = &r->rgb[(row(y) + x) * 3];
      if (o.layer == ImageLayer::kSiteIndex) {
        auto [it, fresh] = index.try_emplace(id, static_cast<uint32_t>(out->site_ids.size() + 1));
        if (fresh) {
          if (it->second >= (1u << 24)) {
            return absl::ResourceExhaustedError(
                "the window shows more than 16,777,215 sites: SITE_INDEX holds 24 bits");
          }
          out->site_ids.push_back(src.site_id(id));
        }
        px[0] = static_cast<uint8_t>(it->second >> 16);
        px[1] = static_cast<uint8_t>(it->second >> 8);
        px[2] = static_cast<uint8_t>(it->second);
        continue;
      }
      const uint32_t feature = o.layer == ImageLayer::kFeatures ? src.feature(x, y, id) : 0;
      SiteColour(src.site_id(id), feature, px);
    }
  }
  return absl::OkStatus();
}

// The image, encoded.
absl::Status Write(const ImageOptions& o, Raster* r, EncodedImage* out) {
  const bool png = o.format == ImageFormat::kPng;
  if (!png) r->spec.text_attributes = {{"compression", "zip"}};
  r->spec.top = !r->rgb.empty()    ? static_cast<const void*>(r->rgb.data())
                : !r->grey.empty() ? static_cast<const void*>(r->grey.data())
                                   : static_cast<const void*>(r->depth.data());
  if (auto s = EncodeRaster(png ? "image.png" : "image.exr", r->spec, &out->bytes); !s.ok()) {
    return s;
  }
  out->mime_type = png ? "image/png" : "image/x-exr";
  return absl::OkStatus();
}

// A feature as a colour's number: 1 + its index and kind.
uint32_t FeatureCode(uint32_t index, FeatureKind kind) {
  return 1 + (index << 2 | static_cast<uint32_t>(kind));
}

}  // namespace

absl::StatusOr<EncodedImage> EncodeImage(const Frame& f, const ImageOptions& o) {
  const PixelRect& rect = o.rect;
  std::vector<uint32_t> scratch;  // Shown's
  PixelSource src;
  src.width = rect.width();
  src.height = rect.height();
  src.shown = [&](uint32_t x, uint32_t y) { return Shown(f, rect.x0 + x, rect.y0 + y, &scratch); };
  src.site_id = [&](uint32_t id) -> const std::string& { return f.sites().get(id - 1)->id; };
  src.feature = [&](uint32_t x, uint32_t y, uint32_t id) {
    const FeatureHit hit =
        NearestFeature(f.grid().Center(rect.x0 + x, rect.y0 + y), *f.sites().get(id - 1));
    return FeatureCode(hit.index, hit.kind);
  };
  EncodedImage out;
  Raster r;
  if (auto s = Fill(src, o, &r, &out); !s.ok()) return s;
  const bool png = o.format == ImageFormat::kPng;
  const uint32_t w = src.width, h = src.height;
  if (o.draw_sites || !o.polyline.empty()) {
    if (!png) return absl::InvalidArgumentError("draw_sites and polyline need format PNG");
    if (r.rgb.empty()) {  // a distance layer: grey to RGB
      r.rgb.resize(size_t{w} * h * 3);
      for (size_t k = 0; k < r.grey.size(); ++k) {
        r.rgb[3 * k] = r.rgb[3 * k + 1] = r.rgb[3 * k + 2] = r.grey[k] >> 8;
      }
      r.spec = {.width = w, .height = h, .channels = 3, .type = "uint8"};
      r.grey.clear();
    }
    if (o.draw_sites) DrawSites(f, rect, &r.rgb);
    static constexpr uint8_t kRed[3] = {255, 32, 32};
    const int thick = std::max<int>(3, std::min(w, h) / 256 * 2 + 1);
    for (size_t k = 1; k < o.polyline.size(); ++k) {
      DrawSegment(f.grid(), rect, o.polyline[k - 1], o.polyline[k], kRed, thick, &r.rgb);
    }
  }
  if (auto s = Write(o, &r, &out); !s.ok()) return s;
  return out;
}

absl::StatusOr<EncodedImage> EncodeImage(const Volume& v, const ImageOptions& o) {
  if (o.draw_sites || !o.polyline.empty()) {
    return absl::InvalidArgumentError("draw_sites and polyline are for 2D scenes");
  }
  const PixelRect& rect = o.rect;
  const uint32_t k = o.slice;
  PixelSource src;
  src.width = rect.width();
  src.height = rect.height();
  // Every voxel's site is a candidate there (a volume's render is exact per voxel).
  src.shown = [&](uint32_t x, uint32_t y) {
    const uint32_t id = v.id_at(rect.x0 + x, rect.y0 + y, k);
    return ShownSite{id, id == 0 ? 0.0 : double{v.distance_at(rect.x0 + x, rect.y0 + y, k)}};
  };
  src.site_id = [&](uint32_t id) -> const std::string& { return v.sites().get(id - 1)->id; };
  src.feature = [&](uint32_t x, uint32_t y, uint32_t id) {
    const Hit3 hit = NearestFeature(v.grid().Center(rect.x0 + x, rect.y0 + y, k),
                                    v.sites().get(id - 1)->geometry);
    return FeatureCode(hit.index, hit.kind);
  };
  EncodedImage out;
  Raster r;
  if (auto s = Fill(src, o, &r, &out); !s.ok()) return s;
  if (auto s = Write(o, &r, &out); !s.ok()) return s;
  return out;
}

}  // namespace gvd

// The plane as the 2D kernel samples it: windows (axis-aligned rectangles of the plane), the
// pixel grid that samples a window, and rectangles of its pixels.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "render/kernel/vec.h"

namespace gvd {

// An axis-aligned rectangle; valid when min < max on both axes and all values are finite.
struct Window {
  double min_x = 0;
  double min_y = 0;
  double max_x = 0;
  double max_y = 0;

  double width() const { return max_x - min_x; }
  double height() const { return max_y - min_y; }
  double diagonal() const { return std::hypot(width(), height()); }
  bool Contains(Vec2 p) const {
    return p.x >= min_x && p.x <= max_x && p.y >= min_y && p.y <= max_y;
  }
  // Distance from p to the farthest point of the window (one of its corners).
  double FarthestDistance(Vec2 p) const;
};

// A rectangle of pixels [x0, x1) x [y0, y1).
struct PixelRect {
  uint32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  bool empty() const { return x0 >= x1 || y0 >= y1; }
  uint32_t width() const { return empty() ? 0 : x1 - x0; }
  uint32_t height() const { return empty() ? 0 : y1 - y0; }
  uint64_t area() const { return uint64_t{width()} * height(); }
  bool operator==(const PixelRect&) const = default;
  bool Intersects(const PixelRect& o) const {
    return !empty() && !o.empty() && x0 < o.x1 && o.x0 < x1 && y0 < o.y1 && o.y0 < y1;
  }
  // The smallest rectangle holding both.
  PixelRect Union(const PixelRect& o) const {
    if (empty()) return o;
    if (o.empty()) return *this;
    return {std::min(x0, o.x0), std::min(y0, o.y0), std::max(x1, o.x1), std::max(y1, o.y1)};
  }
};

// A window sampled at the centres of width x height pixels. Pixel (i, j) covers
// [min_x + i*pw, min_x + (i+1)*pw) x [min_y + j*ph, ...); row j = 0 is at min_y.
struct Grid {
  Window window;
  uint32_t width = 0;
  uint32_t height = 0;

  double pixel_width() const { return window.width() / width; }
  double pixel_height() const { return window.height() / height; }
  // The longer side of a pixel: the scene length of "one pixel".
  double pixel_size() const { return std::max(pixel_width(), pixel_height()); }
  double pixel_diagonal() const { return std::hypot(pixel_width(), pixel_height()); }
  uint64_t pixel_count() const { return uint64_t{width} * height; }

  Vec2 Center(uint32_t i, uint32_t j) const {
    return {window.min_x + (i + 0.5) * pixel_width(), window.min_y + (j + 0.5) * pixel_height()};
  }
  // Continuous pixel coordinates of p: pixel centres sit at integer + 0.5.
  Vec2 ToPixel(Vec2 p) const {
    return {(p.x - window.min_x) / pixel_width(), (p.y - window.min_y) / pixel_height()};
  }
  PixelRect all() const { return {0, 0, width, height}; }
  // The rectangle spanned by the pixel centres of `r` (not empty).
  Window CentreBox(PixelRect r) const {
    Vec2 lo = Center(r.x0, r.y0), hi = Center(r.x1 - 1, r.y1 - 1);
    return {lo.x, lo.y, hi.x, hi.y};
  }
  // The area the pixels of `r` cover, cut to the grid grown by a pixel (so that a rectangle
  // reaching past the grid stays finite).
  Window Area(PixelRect r) const {
    auto at = [](uint32_t i, uint32_t n, double lo, double size) {
      return lo + std::min(i, n + 1) * size;
    };
    return {at(r.x0, width, window.min_x, pixel_width()), at(r.y0, height, window.min_y, pixel_height()),
            at(r.x1, width, window.min_x, pixel_width()), at(r.y1, height, window.min_y, pixel_height())};
  }
  // The pixels whose centres lie within the axis-aligned box [lo, hi].
  PixelRect CentresIn(Vec2 lo, Vec2 hi) const {
    Vec2 a = ToPixel(lo), b = ToPixel(hi);
    auto first = [](double v, uint32_t n) {  // smallest i with i + 0.5 >= v
      double f = std::ceil(v - 0.5);
      return f <= 0 ? 0u : f >= n ? n : static_cast<uint32_t>(f);
    };
    auto past = [](double v, uint32_t n) {  // 1 + largest i with i + 0.5 <= v
      double f = std::floor(v - 0.5) + 1;
      return f <= 0 ? 0u : f >= n ? n : static_cast<uint32_t>(f);
    };
    return {first(a.x, width), first(a.y, height), past(b.x, width), past(b.y, height)};
  }
};

// How far beyond a site's max_distance, and beyond the side of a polygon it excludes, its
// distance function is still drawn: two pixel diagonals. A site that is a candidate at a
// query point q is then drawn at the four pixel centres around q (within one diagonal of
// q), which is what Frame's bounds rest on; an empty pixel centre proves that no site is a
// candidate near it.
inline double DrawMargin(const Grid& grid) { return 2 * grid.pixel_diagonal(); }

inline double Window::FarthestDistance(Vec2 p) const {
  double dx = std::max(std::abs(p.x - min_x), std::abs(p.x - max_x));
  double dy = std::max(std::abs(p.y - min_y), std::abs(p.y - max_y));
  return Length({dx, dy});
}

}  // namespace gvd

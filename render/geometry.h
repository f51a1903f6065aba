// Plane geometry shared by every layer: vectors, windows and the pixel grid that samples them.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace gvd {

struct Vec2 {
  double x = 0;
  double y = 0;
};

inline Vec2 operator-(Vec2 a, Vec2 b) { return {a.x - b.x, a.y - b.y}; }
inline Vec2 operator+(Vec2 a, Vec2 b) { return {a.x + b.x, a.y + b.y}; }
inline Vec2 operator*(double s, Vec2 a) { return {s * a.x, s * a.y}; }
inline double Dot(Vec2 a, Vec2 b) { return a.x * b.x + a.y * b.y; }
// Euclidean length, without undue overflow or underflow.
inline double Length(Vec2 a) { return std::hypot(a.x, a.y); }
inline double Distance(Vec2 a, Vec2 b) { return Length(a - b); }

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
  double FarthestDistance(Vec2 p) const {
    double dx = std::max(std::abs(p.x - min_x), std::abs(p.x - max_x));
    double dy = std::max(std::abs(p.y - min_y), std::abs(p.y - max_y));
    return std::hypot(dx, dy);
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
};

}  // namespace gvd

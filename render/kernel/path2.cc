#include "render/kernel/path2.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <utility>

namespace gvd {
namespace {

std::vector<Vec2> ControlOf(const PathPiece& piece) {
  return {piece.control.begin(), piece.control.begin() + piece.degree + 1};
}

// The distance from q to the rectangle holding the piece's control points: no point of the
// piece is nearer.
double BoxDistance(Vec2 q, const PathPiece& piece) {
  Vec2 lo = piece.control[0], hi = piece.control[0];
  for (int i = 1; i <= piece.degree; ++i) {
    lo = glm::min(lo, piece.control[i]);
    hi = glm::max(hi, piece.control[i]);
  }
  const Vec2 outside = glm::max(glm::max(lo - q, q - hi), Vec2(0));
  return Length(outside);
}

// The nearest point of piece k: its parameter and distance.
std::pair<double, double> NearestOnPiece(Vec2 q, const PathPiece& piece, Vec2* closest) {
  if (piece.degree == 1) {
    double t = 0;
    const double d = SegmentDistance(q, piece.control[0], piece.control[1], &t);
    *closest = t == 0   ? piece.control[0]
               : t == 1 ? piece.control[1]
                        : piece.control[0] + t * (piece.control[1] - piece.control[0]);
    return {t, d};
  }
  const CurvePoint c = NearestOnBezier(q, ControlOf(piece));
  *closest = c.point;
  return {c.t, c.distance};
}

// The ray from q towards +x: +1 where the line ab crosses it going up, -1 going down (a
// crossing counted where one end lies above q and the other not, as InsidePolygon counts).
int LineCrossing(Vec2 q, Vec2 a, Vec2 b) {
  if ((a.y > q.y) == (b.y > q.y)) return 0;
  const double x = a.x + (q.y - a.y) / (b.y - a.y) * (b.x - a.x);
  if (!(q.x < x)) return 0;
  return b.y > a.y ? 1 : -1;
}

}  // namespace

std::string PathContractError(const std::vector<Subpath>& subpaths, Side side) {
  if (subpaths.empty()) return "has no subpath";
  for (size_t i = 0; i < subpaths.size(); ++i) {
    const Subpath& s = subpaths[i];
    const std::string at = "subpath " + std::to_string(i);
    if (s.degrees.empty()) return at + " has no piece";
    size_t points = 1;
    for (size_t k = 0; k < s.degrees.size(); ++k) {
      if (s.degrees[k] < 1 || s.degrees[k] > 3) {
        return at + ": piece " + std::to_string(k) + " has degree " +
               std::to_string(s.degrees[k]) + "; each is 1 (a line), 2 or 3 (a Bezier)";
      }
      points += s.degrees[k];
    }
    if (s.points.size() != points) {
      return at + " has " + std::to_string(s.points.size()) + " points; its pieces take " +
             std::to_string(points);
    }
    for (Vec2 p : s.points) {
      if (!std::isfinite(p.x) || !std::isfinite(p.y)) return at + " has a point that is not finite";
    }
    if (side != Side::kBoth && !s.closed) {
      return at + " is open; a path restricted to a side has only closed subpaths";
    }
  }
  return "";
}

PathSite MakePath(std::vector<Subpath> subpaths, FillRule fill, Side side, double tolerance,
                  size_t max_points) {
  PathSite path;
  path.fill = fill;
  path.side = side;
  double length = 0;
  for (Subpath& s : subpaths) {
    assert(!s.points.empty() && !s.degrees.empty());
    if (s.closed && s.points.back() != s.points.front()) {
      s.points.push_back(s.points.front());
      s.degrees.push_back(1);
    }
    const uint32_t first_joint = path.joints;
    size_t at = 0;
    for (size_t k = 0; k < s.degrees.size(); ++k) {
      PathPiece piece;
      piece.degree = s.degrees[k];
      assert(piece.degree >= 1 && piece.degree <= 3 && at + piece.degree < s.points.size());
      for (int i = 0; i <= piece.degree; ++i) piece.control[i] = s.points[at + i];
      // A thousandth of each, so that the sum stays finite wherever the points' box does.
      for (int i = 0; i < piece.degree; ++i) length += Distance(piece.control[i], piece.control[i + 1]) / 1000;
      at += piece.degree;
      piece.first_joint = first_joint + static_cast<uint32_t>(k);
      const bool last = k + 1 == s.degrees.size();
      piece.last_joint = last && s.closed ? first_joint : piece.first_joint + 1;
      piece.closed = s.closed;
      path.curved = path.curved || piece.degree > 1;
      path.pieces.push_back(piece);
    }
    path.joints = first_joint + static_cast<uint32_t>(s.degrees.size()) + (s.closed ? 0 : 1);
  }
  if (!(tolerance > 0)) tolerance = length > 0 ? length : 1e-9;
  // Curve i takes ceil(sqrt(k_i / tolerance)) pieces, k_i its FlattenBound, at most
  // kMaxBezierPieces (as MakeBezier, the tolerance widens to what each can keep), and one
  // point more; a line two points. So the drawn points are at most
  // 2 lines + 2 curves + sqrt(1 / tolerance) sum sqrt(k_i), which a tolerance of
  // (sum sqrt(k_i) / (max_points - 2 lines - 2 curves))^2 keeps within max_points.
  size_t lines = 0, curves = 0;
  double roots = 0;
  for (const PathPiece& piece : path.pieces) {
    if (piece.degree == 1) {
      ++lines;
      continue;
    }
    ++curves;
    const double k = FlattenBound(ControlOf(piece));
    tolerance = std::max(tolerance, k / (double(kMaxBezierPieces) * kMaxBezierPieces));
    roots += std::sqrt(k);
  }
  assert(max_points > 2 * lines + 3 * curves);
  if (2 * lines + 2 * curves + roots / std::sqrt(tolerance) > double(max_points)) {
    const double room = double(max_points - 2 * lines - 2 * curves);
    tolerance = std::max(tolerance, (roots / room) * (roots / room) * (1 + 1e-12));
  }
  path.tolerance = tolerance;
  for (PathPiece& piece : path.pieces) {
    piece.flat_begin = static_cast<uint32_t>(path.flat.size());
    if (piece.degree == 1) {
      path.flat.push_back(piece.control[0]);
      path.flat.push_back(piece.control[1]);
    } else {
      const std::vector<Vec2> flat = Flatten(ControlOf(piece), tolerance);
      path.flat.insert(path.flat.end(), flat.begin(), flat.end());
    }
  }
  path.subpaths = std::move(subpaths);
  return path;
}

double PathDistance(Vec2 q, const PathSite& path) { return PathNearestFeature(q, path).distance; }

FeatureHit PathNearestFeature(Vec2 q, const PathSite& path) {
  FeatureHit best{INFINITY, FeatureKind::kVertex, 0, Vec2(NAN)};
  for (uint32_t k = 0; k < path.pieces.size(); ++k) {
    const PathPiece& piece = path.pieces[k];
    if (!(BoxDistance(q, piece) <= best.distance)) continue;
    Vec2 closest;
    const auto [t, d] = NearestOnPiece(q, piece, &closest);
    if (!(d < best.distance)) continue;
    best.distance = d;
    best.closest = closest;
    if (t == 0 || t == 1) {
      best.kind = FeatureKind::kVertex;
      best.index = t == 0 ? piece.first_joint : piece.last_joint;
    } else {
      best.kind = piece.degree == 1 ? FeatureKind::kEdge : FeatureKind::kCurve;
      best.index = k;
    }
  }
  return best;
}

int PathWinding(Vec2 q, const PathSite& path) {
  int winding = 0;
  for (uint32_t k = 0; k < path.pieces.size(); ++k) {
    if (!path.pieces[k].closed) continue;
    ForEachPieceSegment(path, k, [&](Vec2 a, Vec2 b) { winding += LineCrossing(q, a, b); });
  }
  return winding;
}

bool InsidePath(Vec2 q, const PathSite& path) {
  const int winding = PathWinding(q, path);
  return path.fill == FillRule::kEvenOdd ? (winding & 1) != 0 : winding != 0;
}

Window PathBox(const PathSite& path) {
  Window w{INFINITY, INFINITY, -INFINITY, -INFINITY};
  for (const PathPiece& piece : path.pieces) {
    for (int i = 0; i <= piece.degree; ++i) {
      const Vec2 p = piece.control[i];
      w = {std::min(w.min_x, p.x), std::min(w.min_y, p.y), std::max(w.max_x, p.x),
           std::max(w.max_y, p.y)};
    }
  }
  return w;
}

double PathFarthestDistance(const Window& rect, const PathSite& path) {
  // As for any chain of segments (FarthestDistance, exact2.h), over the drawn polylines; a
  // curve strays from its own by at most the tolerance.
  const Vec2 corners[4] = {{rect.min_x, rect.min_y}, {rect.max_x, rect.min_y},
                           {rect.min_x, rect.max_y}, {rect.max_x, rect.max_y}};
  double best = INFINITY;
  for (uint32_t k = 0; k < path.pieces.size(); ++k) {
    const double stray = path.pieces[k].degree == 1 ? 0.0 : path.tolerance;
    ForEachPieceSegment(path, k, [&](Vec2 a, Vec2 b) {
      double m = 0;
      for (Vec2 c : corners) m = std::max(m, SegmentDistance(c, a, b));
      best = std::min(best, m + stray);
    });
  }
  return best;
}

}  // namespace gvd

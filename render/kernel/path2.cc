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

// The same for the degree-n curve with control points p, split until each piece is settled.
int CurveCrossings(Vec2 q, const std::array<Vec2, 4>& p, int n, int depth) {
  bool all_above = true, none_above = true, all_right = true, none_right = true;
  bool rising = true, falling = true;
  for (int i = 0; i <= n; ++i) {
    const bool above = p[i].y > q.y, right = p[i].x > q.x;
    all_above = all_above && above;
    none_above = none_above && !above;
    all_right = all_right && right;
    none_right = none_right && !right;
    if (i > 0) {
      rising = rising && p[i].y >= p[i - 1].y;
      falling = falling && p[i].y <= p[i - 1].y;
    }
  }
  // The curve lies in its control points' hull: wholly above, below or left of q, it does
  // not cross the ray (or its ends' states agree, and it crosses as often up as down).
  if (all_above || none_above || none_right) return 0;
  // Monotone in y (its control points' y are), it crosses q's level once; right of q, there.
  if ((rising || falling) && all_right) return p[n].y > p[0].y ? 1 : -1;
  if (depth >= 48) return LineCrossing(q, p[0], p[n]);
  std::array<Vec2, 4> w = p, left, right;
  left[0] = w[0];
  right[n] = w[n];
  for (int k = 1; k <= n; ++k) {
    for (int i = 0; i + k <= n; ++i) w[i] = 0.5 * (w[i] + w[i + 1]);
    left[k] = w[0];
    right[n - k] = w[n - k];
  }
  return CurveCrossings(q, left, n, depth + 1) + CurveCrossings(q, right, n, depth + 1);
}

}  // namespace

PathSite MakePath(std::vector<Subpath> subpaths, FillRule fill, Side side, double tolerance) {
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
      for (int i = 0; i < piece.degree; ++i) length += Distance(piece.control[i], piece.control[i + 1]);
      at += piece.degree;
      piece.first_joint = first_joint + static_cast<uint32_t>(k);
      const bool last = k + 1 == s.degrees.size();
      piece.last_joint = last && s.closed ? first_joint : piece.first_joint + 1;
      piece.closed = s.closed;
      path.pieces.push_back(piece);
    }
    path.joints = first_joint + static_cast<uint32_t>(s.degrees.size()) + (s.closed ? 0 : 1);
  }
  if (!(tolerance > 0)) tolerance = length > 0 ? length / 1000 : 1e-9;
  // MakeBezier widens a tolerance its curve's flattening cannot keep.
  for (const PathPiece& piece : path.pieces) {
    if (piece.degree > 1) tolerance = std::max(tolerance, MakeBezier(ControlOf(piece), tolerance).tolerance);
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
  for (const PathPiece& piece : path.pieces) {
    if (!piece.closed) continue;
    winding += piece.degree == 1 ? LineCrossing(q, piece.control[0], piece.control[1])
                                 : CurveCrossings(q, piece.control, piece.degree, 0);
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

#include "render/kernel/bezier.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <limits>
#include <memory>

#include "render/kernel/exact2.h"  // SegmentDistance

namespace gvd {
namespace {

constexpr double kUnit = std::numeric_limits<double>::epsilon() / 2;  // 2^-53
// Pieces are halved at most this often: a piece of 2^-60 of the parameter is shorter than an
// ulp of the curve's size, so its bounds meet.
constexpr int kMaxDepth = 60;

using Controls = std::array<Vec2, 4>;

// A piece of the curve: the parameters [a, b] and its control points, relative to q.
struct Piece {
  double a = 0, b = 1;
  Controls p;
  int depth = 0;
};

// Room for the pieces waiting to be read, left uninitialized: zeroing it would cost more than
// a short search (each pop pushes at most two halves, one level deeper).
class PieceStack {
 public:
  PieceStack() {}  // NOLINT: the slots are written before they are read
  bool empty() const { return top_ == 0; }
  void push(const Piece& piece) {
    assert(top_ < static_cast<int>(slots_.size()));
    std::construct_at(&slots_[top_++].piece, piece);
  }
  Piece pop() { return slots_[--top_].piece; }

 private:
  union Slot {
    Slot() {}
    Piece piece;
  };
  std::array<Slot, kMaxDepth + 2> slots_;
  int top_ = 0;
};

// Each function below is a template on the degree n (2 or 3), so that its loops unroll.

// De Casteljau's split at 1/2 of the degree-n control points p.
template <int n>
void Halve(const Controls& p, Controls* left, Controls* right) {
  Controls w = p;
  (*left)[0] = w[0];
  (*right)[n] = w[n];
  for (int k = 1; k <= n; ++k) {
    for (int i = 0; i + k <= n; ++i) w[i] = 0.5 * (w[i] + w[i + 1]);
    (*left)[k] = w[0];
    (*right)[n - k] = w[n - k];
  }
}

// The product of Bernstein polynomials of degrees n and n - 1 has degree 2n - 1, its
// coefficient k being sum over i + j = k of C(n, i) C(n - 1, j) / C(2n - 1, k) x_i y_j:
// kWeights[n][i][j], for n = 2 and 3.
constexpr auto kWeights = [] {
  constexpr double kBinomial[6][6] = {{1}, {1, 1}, {1, 2, 1}, {1, 3, 3, 1},
                                      {1, 4, 6, 4, 1}, {1, 5, 10, 10, 5, 1}};
  std::array<std::array<std::array<double, 3>, 4>, 4> w{};
  for (int n = 2; n <= 3; ++n) {
    for (int i = 0; i <= n; ++i) {
      for (int j = 0; j < n; ++j) w[n][i][j] = kBinomial[n][i] * kBinomial[n - 1][j] / kBinomial[2 * n - 1][i + j];
    }
  }
  return w;
}();

// The control points of B' (d, degree n - 1) and of B'' (dd, degree n - 2), and the
// largest |d_j|.
template <int n>
double Derivatives(const Controls& p, Controls* d, Controls* dd) {
  double d_max = 0;
  for (int j = 0; j < n; ++j) {
    (*d)[j] = double(n) * (p[j + 1] - p[j]);
    d_max = std::max(d_max, Length((*d)[j]));
  }
  for (int j = 0; j + 1 < n; ++j) (*dd)[j] = double(n - 1) * ((*d)[j + 1] - (*d)[j]);
  return d_max;
}

// The largest |p_i| of the degree-n control points p.
template <int n>
double Largest(const Controls& p) {
  double m = 0;
  for (int i = 0; i <= n; ++i) m = std::max(m, Length(p[i]));
  return m;
}

// A piece's derivatives and sizes, read once for both the reading of its signs and Newton's
// method on it.
template <int n>
struct Hodograph {
  explicit Hodograph(const Controls& p) : d_max(Derivatives<n>(p, &d, &dd)), p_max(Largest<n>(p)) {}
  Controls d, dd;  // B' (degree n - 1) and B'' (degree n - 2)
  double d_max, p_max;
};

enum class Signs { kUnknown, kNoMinimum, kOneMinimum };

struct SignReading {
  Signs signs = Signs::kUnknown;
  // With kOneMinimum: where the polygon of f's coefficients crosses 0, a start for Newton's
  // method near the root (the coefficients' polygon converges to f's graph).
  double start = 0.5;
};

// What the signs of f = (B - q) . B' on the piece say: no minimum of the distance inside it
// (f of one sign, or one change from + to -: a maximum), one minimum (one change from - to
// +), or nothing certain. slack: how far the piece's control points may be from the exact
// ones.
template <int n>
SignReading ReadSigns(const Controls& p, const Hodograph<n>& h, double slack) {
  const Controls& d = h.d;  // B' = sum of d_j b_j^(n-1)
  const double d_max = h.d_max, p_max = h.p_max;
  int signs[6];
  double coefficients[6];
  constexpr int m = 2 * n - 1;
  for (int k = 0; k <= m; ++k) {
    double c = 0;
    for (int i = std::max(0, k - (n - 1)); i <= std::min(n, k); ++i) {
      const int j = k - i;
      c += kWeights[n][i][j] * glm::dot(p[i], d[j]);
    }
    // The sum's rounding (its terms' sizes sum to at most p_max d_max, as the weights sum to
    // 1), and the control points' error: each moves c by at most slack times the other
    // factor, the derivative's points by 2n slack.
    const double error = 16 * kUnit * p_max * d_max + 2 * slack * (d_max + 2 * n * p_max);
    signs[k] = c > error ? 1 : c < -error ? -1 : 0;
    if (signs[k] == 0) return {};
    coefficients[k] = c;
  }
  int changes = 0, at = 0;
  for (int k = 0; k < m; ++k) {
    if (signs[k] != signs[k + 1]) {
      ++changes;
      at = k;
    }
  }
  if (changes == 0 || (changes == 1 && signs[0] > 0)) return {Signs::kNoMinimum};
  if (changes != 1) return {};
  // Coefficient k stands at k / m; the one change is from - to + between `at` and at + 1.
  const double c0 = coefficients[at], c1 = coefficients[at + 1];
  return {Signs::kOneMinimum, (at + c0 / (c0 - c1)) / m};
}

// The degree-n Bezier with control points p at t, by de Casteljau.
template <int n>
Vec2 At(Controls p, double t) {
  for (int k = n; k > 0; --k) {
    for (int i = 0; i < k; ++i) p[i] = p[i] + t * (p[i + 1] - p[i]);
  }
  return p[0];
}

// The minimum within a piece that holds exactly one (f < 0 at its start, > 0 at its end):
// Newton's method on f, kept within a bracket whose ends have certain signs, to a bracket
// narrow enough that the distance over it is known within `enough`, from `start` in (0, 1).
// Returns false where the signs stop being certain first (the caller then halves the piece
// instead). On success, *s is the piece's parameter of the point found, *distance that
// point's distance from q, and *settled whether f is within its rounding of 0 there (a
// Newton step from it would move it by rounding alone).
template <int n>
bool Converge(const Controls& p, const Hodograph<n>& h, double slack, double enough,
              double start, double* s, double* distance, bool* settled) {
  const Controls &d = h.d, &dd = h.dd;
  const double d_max = h.d_max, p_max = h.p_max;
  // f's rounding at a point, as ReadSigns bounds its coefficients'.
  const double error = 8 * (n + 2) * kUnit * p_max * d_max + 2 * slack * (d_max + 2 * n * p_max);
  struct Value {
    double f, slope;
    Vec2 b;  // B(t)
  };
  auto at = [&](double t) {
    const Vec2 b = At<n>(p, t), b1 = At<n - 1>(d, t), b2 = At<n - 2>(dd, t);
    return Value{glm::dot(b, b1), glm::dot(b1, b1) + glm::dot(b, b2), b};
  };
  const double dd_max = Largest<n - 2>(dd);
  // How much nearer than the point at t (distance `at_t`, f there `f`) the minimum in a
  // bracket of width w around t may be: |B'| <= d_max on the piece, so at most d_max w; and
  // as the squared distance's slope is 2f, with |f'| <= d_max^2 + p_max dd_max, at most
  // 2 (|f| + error + |f'| w) w / at_t, the better bound near a minimum.
  auto gap = [&](double w, double f, double at_t) {
    const double linear = d_max * w;
    const double quadratic =
        2 * (std::abs(f) + error + (d_max * d_max + p_max * dd_max) * w) * w / at_t;
    return at_t > 0 ? std::min(linear, quadratic) : linear;
  };
  double lo = 0, hi = 1, t = start > 0 && start < 1 ? start : 0.5;
  for (int step = 0; step < 64; ++step) {
    const Value v = at(t);
    const bool within = !(std::abs(v.f) > error);
    if (v.f > error) {
      hi = t;
    } else if (v.f < -error) {
      lo = t;
    } else {
      // f is within its rounding of 0 here: certify a bracket a little way either side.
      if (!(v.slope > 0)) return false;
      const double step_out = 4 * error / v.slope;
      const double a = std::max(lo, t - step_out), b = std::min(hi, t + step_out);
      if ((a > lo && !(at(a).f < -error)) || (b < hi && !(at(b).f > error))) return false;
      lo = a;
      hi = b;
    }
    const double here = Length(v.b);
    if (gap(hi - lo, v.f, here) <= enough) {
      *s = t;
      *distance = here;
      *settled = within;
      return true;
    }
    const double next = v.slope > 0 ? t - v.f / v.slope : NAN;
    t = next > lo && next < hi ? next : 0.5 * (lo + hi);
  }
  return false;
}

// A few Newton steps on f from an interior t, each kept only where it brings the curve's
// point nearer q: a piece whose bounds met, or Newton's method stopped before f was within
// its rounding of 0, has left t within some ulps of the scale of a minimum, and this takes
// it to the minimum's own rounding.
template <int n>
void Polish(Vec2 q, const Controls& p, CurvePoint* best) {
  Controls d, dd;
  Derivatives<n>(p, &d, &dd);
  for (int step = 0; step < 4 && best->t > 0 && best->t < 1; ++step) {
    const Vec2 r = best->point - q, b1 = At<n - 1>(d, best->t), b2 = At<n - 2>(dd, best->t);
    const double f = glm::dot(r, b1), slope = glm::dot(b1, b1) + glm::dot(r, b2);
    if (!(slope > 0) || f == 0) return;
    const double t = std::clamp(best->t - f / slope, 0.0, 1.0);
    const Vec2 point = At<n>(p, t);
    const double distance = Distance(q, point);
    if (!(distance < best->distance)) return;
    *best = {t, point, distance};
  }
}

template <int n>
CurvePoint Nearest(Vec2 q_given, const std::vector<Vec2>& control) {
  // Coordinates far from 1 in size are scaled by a power of 2 (exactly), so that no
  // difference overflows and no square underflows; the point found is scaled back.
  double size = std::max(std::abs(q_given.x), std::abs(q_given.y));
  for (Vec2 c : control) size = std::max({size, std::abs(c.x), std::abs(c.y)});
  const int exponent = size > 0x1p500 || (size > 0 && size < 0x1p-500) ? -std::ilogb(size) : 0;
  const auto scaled = [exponent](Vec2 v) {
    return exponent == 0 ? v : Vec2(std::ldexp(v.x, exponent), std::ldexp(v.y, exponent));
  };
  const Vec2 q = scaled(q_given);
  Controls points;
  for (int i = 0; i <= n; ++i) points[i] = scaled(control[i]);
  Piece whole;
  double scale = 0;  // the largest distance from q to a control point
  for (int i = 0; i <= n; ++i) {
    whole.p[i] = points[i] - q;
    scale = std::max(scale, Length(whole.p[i]));
  }
  // The best point found: an end to begin with.
  double best = Length(whole.p[0]), best_t = 0;
  bool settled = false;  // best_t is Newton's, with f within its rounding of 0 there
  if (const double end = Length(whole.p[n]); end < best) {
    best = end;
    best_t = 1;
  }
  if (scale > 0) {
    // A piece is done once its bounds are within this of each other.
    const double enough = 64 * kUnit * scale;
    PieceStack stack;
    stack.push(whole);
    while (!stack.empty()) {
      const Piece piece = stack.pop();
      const Controls& p = piece.p;
      // Each halving rounds each control point by at most n ulps of the scale.
      const double slack = (piece.depth * n + 2) * kUnit * scale;
      // The curve lies within `bulge` of its chord, so no point of it is nearer than `lower`,
      // less the rounding of the piece's points and of this sum (`slack` and a few ulps).
      double bulge = 0;
      for (int i = 1; i < n; ++i) bulge = std::max(bulge, SegmentDistance(p[i], p[0], p[n]));
      const double lower = SegmentDistance(Vec2(0), p[0], p[n]) - bulge;
      if (lower - slack - 8 * kUnit * scale > best) continue;
      // Points of the curve: the ends and the middle.
      Controls left, right;
      Halve<n>(p, &left, &right);
      const double ends[3] = {Length(p[0]), Length(left[n]), Length(p[n])};
      const double ts[3] = {piece.a, 0.5 * (piece.a + piece.b), piece.b};
      double upper = INFINITY;
      for (int k = 0; k < 3; ++k) {
        upper = std::min(upper, ends[k]);
        if (ends[k] < best) {
          best = ends[k];
          best_t = ts[k];
          settled = false;
        }
      }
      // Done: halving cannot narrow the bounds past the rounding, which is not in them.
      if (!(upper - lower > enough) || piece.depth >= kMaxDepth) continue;
      const Hodograph<n> h(p);
      const SignReading signs = ReadSigns<n>(p, h, slack);
      if (signs.signs == Signs::kNoMinimum) continue;  // its least is at an end
      double s, distance;
      bool at_root;
      if (signs.signs == Signs::kOneMinimum &&
          Converge<n>(p, h, slack, enough, signs.start, &s, &distance, &at_root)) {
        if (distance < best) {
          best = distance;
          best_t = piece.a + s * (piece.b - piece.a);
          settled = at_root;
        }
        continue;
      }
      stack.push({0.5 * (piece.a + piece.b), piece.b, right, piece.depth + 1});
      stack.push({piece.a, 0.5 * (piece.a + piece.b), left, piece.depth + 1});
    }
  }
  CurvePoint out;
  out.t = best_t;
  out.point = best_t == 0 ? points[0] : best_t == 1 ? points[n] : At<n>(points, best_t);
  out.distance = Distance(q, out.point);
  if (!settled) Polish<n>(q, points, &out);
  if (exponent != 0) {
    out.point = {std::ldexp(out.point.x, -exponent), std::ldexp(out.point.y, -exponent)};
    out.distance = Distance(q_given, out.point);
  }
  return out;
}

}  // namespace

Vec2 BezierPoint(const std::vector<Vec2>& control, double t) {
  assert(control.size() == 3 || control.size() == 4);
  Controls p;
  std::copy(control.begin(), control.end(), p.begin());
  return control.size() == 3 ? At<2>(p, t) : At<3>(p, t);
}

CurvePoint NearestOnBezier(Vec2 q, const std::vector<Vec2>& control) {
  assert(control.size() == 3 || control.size() == 4);
  return control.size() == 3 ? Nearest<2>(q, control) : Nearest<3>(q, control);
}

}  // namespace gvd

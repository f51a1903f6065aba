#include "server/app/convert/queries.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "server/app/convert/common.h"
#include "server/log.h"

namespace gvd {

template <class Request, class P, class Bounds>
absl::Status ToQueryPoints(const Request& r, const Bounds& bounds,
                           const ServerLimits& limits, std::vector<P>* points, bool* outside) {
  constexpr int kWidth = P::length();
  // The packed form of this dimension's points, and the other's.
  const auto& packed = kWidth == 2 ? r.xy() : r.xyz();
  const char* name = kWidth == 2 ? "xy" : "xyz";
  if ((kWidth == 2 ? r.xyz_size() : r.xy_size()) > 0) {
    return Invalid(kWidth == 2 ? "xyz is for 3D scenes; a 2D scene's packed points are xy"
                               : "xy is for 2D scenes; a 3D scene's packed points are xyz");
  }
  if (r.points_size() > 0 && !packed.empty()) {
    return Invalid(absl::StrCat("points and ", name, " are both set; use one form"));
  }
  if (packed.size() % kWidth != 0) {
    return Invalid(absl::StrCat(name, " has ", packed.size(), " values; it needs ",
                                kWidth == 2 ? "x, y pairs" : "x, y, z triples"));
  }
  const size_t n = !packed.empty() ? packed.size() / kWidth : r.points_size();
  if (n == 0) return Invalid("points is empty");
  if (n > limits.max_points_per_query) {
    return absl::ResourceExhaustedError(absl::StrCat(
        !packed.empty() ? name : "points", " has ", n, " points; the limit per query is ",
        limits.max_points_per_query, " (--max-points-per-query)"));
  }
  points->resize(n);
  if (!packed.empty()) {
    for (int i = 0; i < packed.size(); ++i) {
      if (auto s = CheckFinite(packed[i], FieldPath(name)[i]); !s.ok()) return s;
    }
    for (size_t i = 0; i < n; ++i) {
      for (int a = 0; a < kWidth; ++a) (*points)[i][a] = packed[kWidth * i + a];
    }
  } else {
    for (int i = 0; i < r.points_size(); ++i) {
      if (auto s = ToPoint(r.points(i), FieldPath("points")[i], &(*points)[i]); !s.ok()) return s;
    }
  }
  *outside = false;
  for (const P& p : *points) *outside = *outside || !bounds.Contains(p);
  return absl::OkStatus();
}
template absl::Status ToQueryPoints(const v1::FindNearestRequest&, const Window&,
                                    const ServerLimits&, std::vector<Vec2>*, bool*);
template absl::Status ToQueryPoints(const v1::FindNearestRequest&, const Box3&,
                                    const ServerLimits&, std::vector<Vec3>*, bool*);
template absl::Status ToQueryPoints(const v1::FindNearestStreamRequest&, const Window&,
                                    const ServerLimits&, std::vector<Vec2>*, bool*);
template absl::Status ToQueryPoints(const v1::FindNearestStreamRequest&, const Box3&,
                                    const ServerLimits&, std::vector<Vec3>*, bool*);

template <class P>
absl::Status ToPick(const v1::PickRequest& request, P* point, double* max_distance) {
  if (!request.has_point()) return Invalid("point is not set");
  if (auto s = ToPoint(request.point(), "point", point); !s.ok()) return s;
  const double limit = request.max_distance();
  if (!std::isfinite(limit) || limit < 0) {
    return Invalid(absl::StrCat("max_distance is ", FormatNumber(limit),
                                "; it must be finite and not negative (0: no limit)"));
  }
  *max_distance = limit == 0 ? INFINITY : limit;
  return absl::OkStatus();
}
template absl::Status ToPick(const v1::PickRequest&, Vec2*, double*);
template absl::Status ToPick(const v1::PickRequest&, Vec3*, double*);

}  // namespace gvd

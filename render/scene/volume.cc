#include "render/scene/volume.h"

#include <algorithm>
#include <utility>

namespace gvd {

namespace {

// The voxel whose centre is the greatest at or below c on an axis of n voxels (clamped).
uint32_t FloorCenter(double c, uint32_t n) {
  const double f = std::floor(c - 0.5);
  if (!(f > 0)) return 0;  // also NaN
  if (f >= n - 1) return n - 1;
  return static_cast<uint32_t>(f);
}

double Magnitude(const Box3& b) {
  return std::max({std::abs(b.min_x), std::abs(b.min_y), std::abs(b.min_z), std::abs(b.max_x),
                   std::abs(b.max_y), std::abs(b.max_z)});
}

}  // namespace

ErrorModel ExactVolumeError(const Grid3& grid, Diagram diagram, const SiteSnapshot3& sites) {
  ErrorModel e;
  e.diagram = diagram;
  double magnitude = Magnitude(grid.box), lipschitz = 1, additive = 0;
  const SlotTable3& table = sites.sites();
  for (uint32_t s = 0; s < table.size(); ++s) {
    const Site3* site = table.get(s);
    if (site == nullptr) continue;
    magnitude = std::max(magnitude, Magnitude(BoundingBox(site->geometry)));
    lipschitz = std::max(lipschitz, site->multiplicative);
    additive = std::max(additive, site->additive);
    if (std::isfinite(site->max_distance)) e.limited_presence = true;
  }
  e.lipschitz = lipschitz;
  // A distance computed in double among coordinates of magnitude M is off by a few units in
  // the last place of M (2^-52 M each); weighted, by L times that, and the additive weight's
  // sum by an ulp of it. Stored in float: half a unit in the last place, 2^-24 relative.
  e.absolute_slack = 0x1p-44 * (magnitude * lipschitz + additive);
  e.relative_slack = 0x1p-22;
  return e;
}

Volume::Volume(Grid3 grid, Diagram diagram, std::vector<std::shared_ptr<const Slice>> slices,
               std::vector<float> brick_extreme, std::shared_ptr<const SiteSnapshot3> sites)
    : grid_(grid),
      error_(ExactVolumeError(grid, diagram, *sites)),
      snapshot_(std::move(sites)),
      slices_(std::move(slices)),
      brick_extreme_(std::move(brick_extreme)) {}

std::shared_ptr<const Volume> Volume::Empty(Grid3 grid, Diagram diagram,
                                            std::shared_ptr<const SiteSnapshot3> sites) {
  auto slice = std::make_shared<Slice>();
  const float none = diagram == Diagram::kNearest ? INFINITY : -INFINITY;
  slice->ids.assign(grid.slice_size(), 0);
  slice->distances.assign(grid.slice_size(), none);
  const size_t bricks = size_t{(grid.width + kBrick - 1) / kBrick} *
                        ((grid.height + kBrick - 1) / kBrick) * ((grid.depth + kBrick - 1) / kBrick);
  return std::make_shared<const Volume>(
      grid, diagram, std::vector<std::shared_ptr<const Slice>>(grid.depth, slice),
      std::vector<float>(bricks, none), std::move(sites));
}

std::optional<NearestAnswer> Volume::Nearest(Vec3 q, Hit3* feature) const {
  if (empty()) return std::nullopt;
  // The nearest feature of the site at slot hit_site, when a mesh's value was found by it.
  Hit3 hit;
  uint32_t hit_site = UINT32_MAX;
  auto finish = [&](const NearestAnswer& a) {
    if (feature != nullptr && a.found) {
      *feature = a.site_index == hit_site ? hit : NearestFeature(q, sites().get(a.site_index)->geometry);
    }
    return a;
  };
  const bool nearest = error_.diagram == Diagram::kNearest;
  NearestAnswer none;
  none.found = false;
  if (!nearest) return finish(Refine(q, none));
  if (error_.limited_presence) {
    // The nearest site by distance starts the search when it is a candidate at q.
    const ExactNearest n = snapshot_->index().Nearest(q);
    const double value = SiteValue(q, *sites().get(static_cast<uint32_t>(n.index)));
    if (!std::isfinite(value)) return finish(Refine(q, none));
    return finish(Refine(q, {static_cast<uint32_t>(n.index), value, 0, true}));
  }
  const Vec3 c = grid_.ToVoxel(q);
  const uint32_t i0 = FloorCenter(c.x, grid_.width), j0 = FloorCenter(c.y, grid_.height),
                 k0 = FloorCenter(c.z, grid_.depth);
  const uint32_t is[2] = {i0, std::min(i0 + 1, grid_.width - 1)};
  const uint32_t js[2] = {j0, std::min(j0 + 1, grid_.height - 1)};
  const uint32_t ks[2] = {k0, std::min(k0 + 1, grid_.depth - 1)};
  NearestAnswer best;
  best.found = false;
  double limit = -INFINITY;  // no site's value at q is below it
  double runner_up = INFINITY;
  for (uint32_t a = 0; a < 2; ++a) {
    for (uint32_t b = 0; b < 2; ++b) {
      for (uint32_t d = 0; d < 2; ++d) {
        if ((a && is[1] == is[0]) || (b && js[1] == js[0]) || (d && ks[1] == ks[0])) continue;
        const uint32_t i = is[a], j = js[b], k = ks[d];
        const uint32_t id = id_at(i, j, k);
        // Every site is a candidate everywhere (no max_distance): a voxel holds one.
        // v_B(q) >= v_B(c) - L |q - c| >= LowerBound(D) - L |q - c| for every site B.
        const double stored = distance_at(i, j, k);
        const double step = error_.lipschitz * Distance(q, grid_.Center(i, j, k));
        limit = std::max(limit, error_.LowerBound(stored) - step);
        const uint32_t s = id - 1;
        if (id == 0 || (best.found && s == best.site_index) || sites().get(s) == nullptr) continue;
        const Site3& site = *sites().get(s);
        // A mesh's value, when its feature is asked for, from its nearest feature.
        std::optional<Hit3> h;
        if (feature != nullptr && std::holds_alternative<MeshSite3>(site.geometry)) {
          h = NearestFeature(q, site.geometry);
        }
        const double value = !h ? SiteValue(q, site)
                             : h->distance <= site.max_distance
                                 ? site.multiplicative * h->distance + site.additive
                                 : INFINITY;
        if (!best.found || value < best.distance || (value == best.distance && s < best.site_index)) {
          if (best.found) runner_up = std::min(runner_up, best.distance);
          best = {s, value, 0, true};
          if (h) {
            hit = *h;
            hit_site = s;
          }
        } else {
          runner_up = std::min(runner_up, value);
        }
      }
    }
  }
  if (!best.found) return finish(Refine(q, best));
  // Outside the box the bound would grow with the distance to it: answered exactly instead,
  // the raster's site bounding the search.
  if (!grid_.box.Contains(q)) return finish(Refine(q, best));
  best.error_bound = std::max(0.0, best.distance - limit);
  best.exact = best.error_bound == 0;
  best.runner_up = runner_up;
  return finish(best);
}

NearestAnswer Volume::Refine(Vec3 q, const NearestAnswer& answer) const {
  const Diagram diagram = error_.diagram;
  NearestAnswer best = answer;
  best.runner_up = diagram == Diagram::kNearest ? INFINITY : -INFINITY;
  auto consider = [&](uint32_t s) {
    const Site3* site = sites().get(s);
    if (site == nullptr || (best.found && s == best.site_index)) return;
    const double value = SiteValue(q, *site);
    if (!std::isfinite(value)) return;
    if (!best.found || Beats(diagram, value, best.distance) ||
        (value == best.distance && s < best.site_index)) {
      if (best.found) best.runner_up = best.distance;
      best = {s, value, 0, true, best.runner_up};
    } else if (Beats(diagram, value, best.runner_up)) {
      best.runner_up = value;
    }
  };
  if (diagram == Diagram::kNearest && answer.found && std::isfinite(answer.distance)) {
    // A site beats value V only where m d + a < V, so d < (V - least a) / least m.
    const LeastWeights& least = snapshot_->least();
    thread_local std::vector<uint32_t> near;
    near.clear();
    snapshot_->index().Within(
        q, (answer.distance - least.additive) / least.multiplicative * (1 + 1e-12), &near);
    for (uint32_t s : near) consider(s);
  } else {
    for (uint32_t s = 0; s < sites().size(); ++s) consider(s);
  }
  best.error_bound = 0;
  best.exact = true;
  return best;
}

}  // namespace gvd

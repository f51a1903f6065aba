#include "render/plan/volume_scan.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <utility>
#include <vector>

#include "render/kernel/exact3.h"
#include "render/kernel/mesh_regions.h"
#include "render/scene/cpu_pool.h"

namespace gvd {

namespace {

using Slice = Volume::Slice;
constexpr uint32_t kBrick = Volume::kBrick;

struct Candidate {
  uint32_t slot;
  double lower;  // the least value the site can take at a centre of the brick
  const Site3* site;
  Vec3 point;  // a plain point's position; NaN otherwise
  const MeshSite3* mesh;  // a mesh's geometry; null otherwise
  // A mesh's distances over the brick (MeshRegions::Distances), made when first needed.
  bool ready = false;
};

// Renders bricks of one volume into slices being written (each brick's voxels are its own,
// so bricks render concurrently).
class BrickScan {
 public:
  BrickScan(const Grid3& grid, Diagram diagram, const SiteSnapshot3& sites)
      : grid_(grid), diagram_(diagram), sites_(sites) {}

  // Renders brick (bx, by, bz) into `slices` and returns its extreme stored value; adds to
  // the pairs it scored.
  float Render(uint32_t bx, uint32_t by, uint32_t bz, const std::vector<Slice*>& slices,
               std::atomic<uint64_t>* pairs) const {
    const VoxelBox vb{bx * kBrick,
                      by * kBrick,
                      bz * kBrick,
                      std::min((bx + 1) * kBrick, grid_.width),
                      std::min((by + 1) * kBrick, grid_.height),
                      std::min((bz + 1) * kBrick, grid_.depth)};
    const bool nearest = diagram_ == Diagram::kNearest;
    thread_local std::vector<Candidate> candidates;
    Candidates(vb, &candidates);
    // The meshes' distances over the brick: candidate c's at [c * kBrick^3, ...).
    thread_local std::vector<double> meshes;
    meshes.resize(candidates.size() * kBrick * kBrick * kBrick);
    const uint32_t nx = vb.x1 - vb.x0, ny = vb.y1 - vb.y0;
    pairs->fetch_add(candidates.size(), std::memory_order_relaxed);
    const float none = nearest ? INFINITY : -INFINITY;
    float extreme = nearest ? -INFINITY : INFINITY;
    for (uint32_t k = vb.z0; k < vb.z1; ++k) {
      Slice& slice = *slices[k];
      for (uint32_t j = vb.y0; j < vb.y1; ++j) {
        for (uint32_t i = vb.x0; i < vb.x1; ++i) {
          const Vec3 p = grid_.Center(i, j, k);
          uint32_t best_slot = 0;
          double best = nearest ? INFINITY : -INFINITY;
          bool found = false;
          const size_t local = (size_t{k - vb.z0} * ny + (j - vb.y0)) * nx + (i - vb.x0);
          for (size_t n = 0; n < candidates.size(); ++n) {
            Candidate& c = candidates[n];
            // Sorted by lower bound: none further on can do better.
            if (found && nearest && c.lower > best) break;
            double value;
            if (!std::isnan(c.point.x)) {
              value = Distance(p, c.point);
            } else if (c.mesh != nullptr) {
              // A mesh: all its distances over the brick at once, feature by feature.
              double* brick = &meshes[n * kBrick * kBrick * kBrick];
              if (!c.ready) {
                MeshRegions::Distances(*c.mesh, grid_, vb, brick);
                c.ready = true;
              }
              const Site3& s = *c.site;
              const double d = brick[local];
              if (!(d <= s.max_distance)) continue;
              value = s.multiplicative * d + s.additive;
            } else {
              const Site3& s = *c.site;
              // A segment or a triangle.
              const double d = ExactDistance(p, s.geometry);
              if (!(d <= s.max_distance)) continue;
              value = s.multiplicative * d + s.additive;
            }
            if (!found || Beats(diagram_, value, best) || (value == best && c.slot < best_slot)) {
              best = value;
              best_slot = c.slot;
              found = true;
            }
          }
          const size_t at = size_t{j} * grid_.width + i;
          const float stored = found ? static_cast<float>(best) : none;
          slice.ids[at] = found ? best_slot + 1 : 0;
          slice.distances[at] = stored;
          extreme = nearest ? std::max(extreme, stored) : std::min(extreme, stored);
        }
      }
    }
    return extreme;
  }

 private:
  // The sites that can be best at a voxel centre of vb, by the proof in the header, sorted
  // by their least possible value there (kNearest), or every site (kFarthest).
  void Candidates(const VoxelBox& vb, std::vector<Candidate>* out) const {
    out->clear();
    const SlotTable3& table = sites_.sites();
    if (sites_.empty()) return;
    const Box3 cb = grid_.CentreBox(vb);
    const Vec3 lo(cb.min_x, cb.min_y, cb.min_z), hi(cb.max_x, cb.max_y, cb.max_z);
    const Vec3 centre = lo * 0.5 + hi * 0.5;
    const double r = Length(hi - lo) / 2;
    auto add = [&](uint32_t s, double upper) {
      const Site3* site = table.get(s);
      if (site == nullptr) return;
      const double gap = BoxDistance(cb, BoundingBox(site->geometry));
      if (gap > site->max_distance) return;
      const double lower = site->multiplicative * gap + site->additive;
      if (lower > upper) return;
      out->push_back({s, lower, site, table.point(s), std::get_if<MeshSite3>(&site->geometry)});
    };
    double upper = INFINITY;
    if (diagram_ == Diagram::kNearest) {
      const ExactNearest n = sites_.index().Nearest(centre);
      const Site3& s0 = *table.get(static_cast<uint32_t>(n.index));
      if (n.distance + r <= s0.max_distance) {
        upper = (s0.multiplicative * (n.distance + r) + s0.additive) * (1 + 1e-12);
      }
    }
    if (std::isfinite(upper)) {
      const LeastWeights& least = sites_.least();
      thread_local std::vector<uint32_t> near;
      near.clear();
      sites_.index().Within(centre, (upper - least.additive) / least.multiplicative + r, &near);
      for (uint32_t s : near) add(s, upper);
    } else {
      for (uint32_t s = 0; s < table.size(); ++s) add(s, upper);
    }
    if (diagram_ == Diagram::kNearest) {
      std::sort(out->begin(), out->end(), [](const Candidate& a, const Candidate& b) {
        return a.lower < b.lower || (a.lower == b.lower && a.slot < b.slot);
      });
    }
  }

  const Grid3& grid_;
  const Diagram diagram_;
  const SiteSnapshot3& sites_;
};

// Renders the bricks listed (indices, x fastest) of a volume whose slices are `slices` (those
// of the bricks' slices writable copies) and whose brick extremes are `extremes`.
void RenderBricks(const Grid3& grid, Diagram diagram, const SiteSnapshot3& sites,
                  const std::vector<uint32_t>& bricks, const std::vector<Slice*>& writable,
                  std::vector<float>* extremes, VolumeScanStats* stats) {
  const uint32_t bx = (grid.width + kBrick - 1) / kBrick, by = (grid.height + kBrick - 1) / kBrick;
  const BrickScan scan(grid, diagram, sites);
  std::atomic<uint64_t> pairs{0};
  ParallelFor(bricks.size(), 16, [&](size_t begin, size_t end) {
    for (size_t n = begin; n < end; ++n) {
      const uint32_t b = bricks[n];
      (*extremes)[b] = scan.Render(b % bx, b / bx % by, b / bx / by, writable, &pairs);
    }
  });
  if (stats != nullptr) {
    stats->bricks += bricks.size();
    stats->pairs += pairs.load();
    for (uint32_t b : bricks) {
      const uint32_t x = b % bx, y = b / bx % by, z = b / bx / by;
      stats->voxels += VoxelBox{x * kBrick, y * kBrick, z * kBrick,
                                std::min((x + 1) * kBrick, grid.width),
                                std::min((y + 1) * kBrick, grid.height),
                                std::min((z + 1) * kBrick, grid.depth)}
                           .volume();
    }
  }
}

uint64_t BrickCount(const Grid3& grid) {
  return uint64_t{(grid.width + kBrick - 1) / kBrick} * ((grid.height + kBrick - 1) / kBrick) *
         ((grid.depth + kBrick - 1) / kBrick);
}

}  // namespace

std::shared_ptr<const Volume> ScanVolume(const Grid3& grid, Diagram diagram,
                                         std::shared_ptr<const SiteSnapshot3> sites,
                                         VolumeScanStats* stats) {
  std::vector<std::shared_ptr<Slice>> owned(grid.depth);
  std::vector<Slice*> writable(grid.depth);
  for (uint32_t k = 0; k < grid.depth; ++k) {
    owned[k] = std::make_shared<Slice>();
    owned[k]->ids.resize(grid.slice_size());
    owned[k]->distances.resize(grid.slice_size());
    writable[k] = owned[k].get();
  }
  std::vector<uint32_t> bricks(BrickCount(grid));
  for (uint32_t b = 0; b < bricks.size(); ++b) bricks[b] = b;
  std::vector<float> extremes(bricks.size());
  RenderBricks(grid, diagram, *sites, bricks, writable, &extremes, stats);
  if (stats != nullptr) stats->slices += grid.depth;
  return std::make_shared<const Volume>(
      grid, diagram, std::vector<std::shared_ptr<const Slice>>(owned.begin(), owned.end()),
      std::move(extremes), std::move(sites));
}

std::shared_ptr<const Volume> UpdateVolume(const Volume& base,
                                           std::shared_ptr<const SiteSnapshot3> sites,
                                           VolumeScanStats* stats) {
  const Grid3& grid = base.grid();
  const Diagram diagram = base.diagram();
  // A change of many sites is rendered whole: finding its bricks site by site would cost
  // more than the render.
  size_t changes = 0;
  BasicSlotTable<Kernel3>::Diff(base.sites(), sites->sites(),
                                [&](uint32_t, const Site3*, const Site3*) { ++changes; });
  if (changes > std::max<size_t>(64, sites->size() / 8)) {
    auto volume = ScanVolume(grid, diagram, std::move(sites), stats);
    return volume;
  }
  const uint32_t bx = base.bricks_x(), by = base.bricks_y(), bz = base.bricks_z();
  const size_t count = size_t{bx} * by * bz;
  std::vector<uint8_t> dirty(count, 0);
  auto brick_box = [&](uint32_t x, uint32_t y, uint32_t z) {
    return grid.CentreBox({x * kBrick, y * kBrick, z * kBrick, std::min((x + 1) * kBrick, grid.width),
                           std::min((y + 1) * kBrick, grid.height),
                           std::min((z + 1) * kBrick, grid.depth)});
  };
  // No brick's greatest stored value exceeds this: it bounds how far a site can reach.
  float greatest = -INFINITY;
  for (float e : base.brick_extremes()) greatest = std::max(greatest, e);
  // A stored value is a float rounded to nearest from the exact one, which may be up to half
  // an ulp greater: the comparisons take the next float up.
  auto above = [](float f) { return double{std::nextafter(f, INFINITY)}; };
  // The bricks where a site's least possible value is at most the greatest stored value:
  // those within min(max_distance, (greatest - a) / m) of its box, searched among the bricks
  // that meet the box grown by that much.
  auto reach = [&](const Site3& site, auto&& f) {
    const Box3 box = BoundingBox(site.geometry);
    const double r = std::min(site.max_distance,
                              (above(greatest) - site.additive) / site.multiplicative);
    if (!(r >= 0)) return;  // also NaN: no brick holds a finite value
    uint32_t lo[3] = {0, 0, 0}, hi[3] = {bx, by, bz};
    if (std::isfinite(r)) {
      const Vec3 a = grid.ToVoxel(Vec3(box.min_x - r, box.min_y - r, box.min_z - r));
      const Vec3 b = grid.ToVoxel(Vec3(box.max_x + r, box.max_y + r, box.max_z + r));
      for (int axis = 0; axis < 3; ++axis) {
        // Bricks whose voxels' centres (integer + 0.5) can lie in [a, b], a voxel to spare.
        const double first = std::floor(a[axis]) - 1, last = std::floor(b[axis]) + 1;
        lo[axis] = first <= 0 ? 0 : first >= hi[axis] * double{kBrick} ? hi[axis]
                 : static_cast<uint32_t>(first) / kBrick;
        hi[axis] = last < 0 ? 0 : last >= hi[axis] * double{kBrick} ? hi[axis]
                 : static_cast<uint32_t>(last) / kBrick + 1;
      }
    }
    for (uint32_t z = lo[2]; z < hi[2]; ++z) {
      for (uint32_t y = lo[1]; y < hi[1]; ++y) {
        for (uint32_t x = lo[0]; x < hi[0]; ++x) {
          const double gap = BoxDistance(brick_box(x, y, z), box);
          if (gap > site.max_distance) continue;
          if (site.multiplicative * gap + site.additive <= above(base.brick_extreme(x, y, z))) {
            f(x, y, z);
          }
        }
      }
    }
  };
  bool all = false;
  BasicSlotTable<Kernel3>::Diff(
      base.sites(), sites->sites(),
      [&](uint32_t slot, const Site3* before, const Site3* after) {
        if (all) return;
        if (diagram == Diagram::kFarthest) {
          all = true;
          return;
        }
        if (before != nullptr) {
          // The bricks where some voxel holds the old site.
          reach(*before, [&](uint32_t x, uint32_t y, uint32_t z) {
            const size_t b = (size_t{z} * by + y) * bx + x;
            if (dirty[b]) return;
            for (uint32_t k = z * kBrick; k < std::min((z + 1) * kBrick, grid.depth) && !dirty[b]; ++k) {
              for (uint32_t j = y * kBrick; j < std::min((y + 1) * kBrick, grid.height) && !dirty[b]; ++j) {
                for (uint32_t i = x * kBrick; i < std::min((x + 1) * kBrick, grid.width); ++i) {
                  if (base.id_at(i, j, k) == slot + 1) {
                    dirty[b] = 1;
                    break;
                  }
                }
              }
            }
          });
        }
        if (after != nullptr) {
          reach(*after, [&](uint32_t x, uint32_t y, uint32_t z) {
            dirty[(size_t{z} * by + y) * bx + x] = 1;
          });
        }
      });
  std::vector<uint32_t> bricks;
  for (size_t b = 0; b < count; ++b) {
    if (all || dirty[b]) bricks.push_back(static_cast<uint32_t>(b));
  }
  // Copies of the slices the bricks touch; the others are base's.
  std::vector<std::shared_ptr<const Slice>> slices(grid.depth);
  std::vector<Slice*> writable(grid.depth, nullptr);
  std::vector<uint8_t> touched(bz, 0);
  for (uint32_t b : bricks) touched[b / bx / by] = 1;
  for (uint32_t k = 0; k < grid.depth; ++k) {
    if (touched[k / kBrick]) {
      auto copy = std::make_shared<Slice>(*base.slice(k));
      writable[k] = copy.get();
      slices[k] = std::move(copy);
      if (stats != nullptr) ++stats->slices;
    } else {
      slices[k] = base.slice(k);
    }
  }
  std::vector<float> extremes = base.brick_extremes();
  RenderBricks(grid, diagram, *sites, bricks, writable, &extremes, stats);
  return std::make_shared<const Volume>(grid, diagram, std::move(slices), std::move(extremes),
                                        std::move(sites));
}

}  // namespace gvd

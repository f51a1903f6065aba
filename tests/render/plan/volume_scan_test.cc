// The exact render of 3D volumes (render/plan/volume_scan.h) and the answers read from them
// (render/scene/volume.h), against the tests' own oracle (tests/support/oracle3.h) at every
// voxel centre: random and adversarial sites (points, segments, triangles, closed and open
// meshes; zero-length segments, degenerate and coincident triangles, features on slice planes
// and on the box's faces, sites outside the box, weights large and small, reaches), nearest
// and farthest; incremental renders equal full ones voxel for voxel; queries within their
// bounds.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "render/plan/volume_scan.h"
#include "tests/support/meshes3.h"
#include "tests/support/oracle3.h"

namespace gvd {
namespace {

using oracle3::Real;

Vec3 Random(std::mt19937_64& rng, double lo, double hi) {
  std::uniform_real_distribution<double> u(lo, hi);
  return {u(rng), u(rng), u(rng)};
}

// The oracle's value of a site at q: +inf (kNearest's none) beyond its reach.
Real OracleValue(Vec3 q, const Site3& s) {
  const Real d = oracle3::ToGeometry(q, s.geometry);
  if (d > s.max_distance) return INFINITY;
  return Real(s.multiplicative) * d + Real(s.additive);
}

// A voxel centre as the tests compute it: the box split evenly, the centre of each part.
Vec3 Centre(const Box3& b, uint32_t w, uint32_t h, uint32_t d, uint32_t i, uint32_t j, uint32_t k) {
  return {b.min_x + (b.max_x - b.min_x) * (2 * i + 1) / (2.0 * w),
          b.min_y + (b.max_y - b.min_y) * (2 * j + 1) / (2.0 * h),
          b.min_z + (b.max_z - b.min_z) * (2 * k + 1) / (2.0 * d)};
}

// Every voxel of `volume` against the oracle: its value is the best value there, its site
// takes that value (or one within the tolerance: a tie), and an empty voxel has no candidate.
void CheckEveryVoxel(const Volume& volume, const std::vector<Site3>& sites, const std::string& what) {
  const Grid3& g = volume.grid();
  const bool nearest = volume.diagram() == Diagram::kNearest;
  int failures = 0;
  for (uint32_t k = 0; k < g.depth; ++k) {
    for (uint32_t j = 0; j < g.height; ++j) {
      for (uint32_t i = 0; i < g.width; ++i) {
        const Vec3 p = Centre(g.box, g.width, g.height, g.depth, i, j, k);
        Real best = nearest ? INFINITY : -INFINITY;
        for (const Site3& s : sites) {
          const Real v = OracleValue(p, s);
          if (!std::isfinite(double(v))) continue;
          best = nearest ? std::min(best, v) : std::max(best, v);
        }
        const uint32_t id = volume.id_at(i, j, k);
        const double stored = volume.distance_at(i, j, k);
        if (!std::isfinite(double(best))) {
          if (id != 0 && ++failures < 10) ADD_FAILURE() << what << " voxel " << i << "," << j << "," << k << " holds " << id << ", no site is a candidate";
          continue;
        }
        const double tol = 1e-6 * (1 + std::abs(double(best)));
        if (id == 0) {
          if (++failures < 10) ADD_FAILURE() << what << " voxel " << i << "," << j << "," << k << " is empty; best " << double(best);
          continue;
        }
        const Site3* site = volume.sites().get(id - 1);
        ASSERT_NE(site, nullptr);
        const Real mine = OracleValue(p, *site);
        if (std::abs(stored - double(best)) > tol || std::abs(double(mine - best)) > tol) {
          if (++failures < 10) {
            ADD_FAILURE() << what << " voxel " << i << "," << j << "," << k << ": stored " << stored
                          << " (site " << site->id << ", value " << double(mine) << "), best "
                          << double(best);
          }
        }
      }
    }
  }
  EXPECT_EQ(failures, 0) << what;
}

std::shared_ptr<const SiteSnapshot3> Snapshot(const std::vector<Site3>& sites) {
  return SiteSnapshot3::Of(1, sites);
}

const Box3 kBox{0, 0, 0, 10, 8, 6};
const Grid3 kGrid{kBox, 20, 16, 12};

std::vector<Site3> RandomSites(std::mt19937_64& rng, int n, bool weighted) {
  std::vector<Site3> sites;
  const MeshSite3 sphere = Icosphere(1), torus = Torus(1, 0.3, 12, 8), patch = Patch(6);
  for (int i = 0; i < n; ++i) {
    Site3 s;
    s.id = "s" + std::to_string(i);
    const Vec3 a = Random(rng, -2, 12);  // some outside the box
    switch (rng() % 7) {
      case 0: s.geometry = PointSite3{a}; break;
      case 1: s.geometry = SegmentSite3{a, a + Random(rng, -3, 3)}; break;
      case 2: s.geometry = SegmentSite3{a, a}; break;  // zero length
      case 3: s.geometry = TriangleSite3{a, a + Random(rng, -3, 3), a + Random(rng, -3, 3)}; break;
      case 4: s.geometry = Placed(sphere, a, 1 + rng() % 2); break;
      case 5: s.geometry = Placed(torus, a, 1); break;
      default: s.geometry = Placed(patch, a, 3); break;
    }
    if (weighted && rng() % 2) {
      s.multiplicative = std::uniform_real_distribution<double>(0.5, 3)(rng);
      s.additive = std::uniform_real_distribution<double>(0, 2)(rng);
    }
    if (weighted && rng() % 3 == 0) s.max_distance = std::uniform_real_distribution<double>(0.5, 4)(rng);
    sites.push_back(std::move(s));
  }
  return sites;
}

TEST(VolumeScan, EveryVoxelAgainstTheOracle) {
  std::mt19937_64 rng(2026);
  for (int round = 0; round < 3; ++round) {
    const auto sites = RandomSites(rng, 4 + 8 * round, false);
    CheckEveryVoxel(*ScanVolume(kGrid, Diagram::kNearest, Snapshot(sites)), sites,
                    "plain " + std::to_string(round));
  }
  for (int round = 0; round < 3; ++round) {
    const auto sites = RandomSites(rng, 6 + 6 * round, true);
    CheckEveryVoxel(*ScanVolume(kGrid, Diagram::kNearest, Snapshot(sites)), sites,
                    "weighted " + std::to_string(round));
    CheckEveryVoxel(*ScanVolume(kGrid, Diagram::kFarthest, Snapshot(sites)), sites,
                    "farthest " + std::to_string(round));
  }
}

TEST(VolumeScan, AdversarialSites) {
  // Features on slice planes (z = 0.25 + k 0.5) and on the box's faces, a coincident pair of
  // triangles (a tie everywhere), a degenerate triangle, a point exactly at a voxel centre,
  // a huge additive weight that never wins and a tiny multiplicative one that wins far off.
  const double slice = 0.25 + 0.5 * 5;
  std::vector<Site3> sites = {
      {"on-slice", TriangleSite3{{1, 1, slice}, {4, 1, slice}, {1, 5, slice}}},
      {"twin", TriangleSite3{{1, 1, slice}, {4, 1, slice}, {1, 5, slice}}},
      {"face", SegmentSite3{{0, 0, 0}, {10, 8, 0}}},
      {"flat", TriangleSite3{{6, 6, 1}, {7, 7, 2}, {8, 8, 3}}},
      {"centre", PointSite3{{0.25, 0.25, 0.25}}},
      {"mesh", Placed(Icosphere(2), {7, 3, 3}, 1.5)},
  };
  Site3 heavy{"heavy", PointSite3{{5, 4, 3}}};
  heavy.additive = 1e12;
  sites.push_back(heavy);
  Site3 light{"light", PointSite3{{50, 40, 30}}};
  light.multiplicative = 0.01;
  sites.push_back(light);
  const auto volume = ScanVolume(kGrid, Diagram::kNearest, Snapshot(sites));
  CheckEveryVoxel(*volume, sites, "adversarial");
  // The twins tie everywhere near them: the lesser slot (on-slice, slot 0) holds them.
  EXPECT_EQ(volume->id_at(4, 4, 5), 1u);
  CheckEveryVoxel(*ScanVolume(kGrid, Diagram::kFarthest, Snapshot(sites)), sites, "adversarial farthest");
}

// A sequence of changes rendered incrementally equals a full render of each version, voxel
// for voxel, and a small change shares most slices.
TEST(VolumeScan, UpdatesEqualAFullScan) {
  std::mt19937_64 rng(7);
  for (Diagram diagram : {Diagram::kNearest, Diagram::kFarthest}) {
    auto sites = RandomSites(rng, 25, diagram == Diagram::kNearest);
    std::vector<uint32_t> free_slots;
    auto snapshot = Snapshot(sites);
    auto volume = ScanVolume(kGrid, diagram, snapshot);
    bool shared_some = false;
    for (int step = 0; step < 12; ++step) {
      std::vector<SiteChange3> changes;
      const int kind = step % 4;
      if (kind == 0) {  // a small move of one point-like site
        Site3 s{"p" + std::to_string(step), PointSite3{Random(rng, 0, 10) * Vec3(1, 0.8, 0.6)}};
        changes.emplace_back(s.id, s);
      } else if (kind == 1) {  // a new mesh
        Site3 s{"m" + std::to_string(step), Placed(Torus(1, 0.3, 10, 6), Random(rng, 0, 8), 1)};
        changes.emplace_back(s.id, s);
      } else if (kind == 2) {  // delete one
        const auto& ids = snapshot->ids();
        std::vector<std::string> all;
        ids.ForEachAfter("", [&](const IdMap::Entry& e) { all.push_back(e.id); return true; });
        changes.emplace_back(all[rng() % all.size()], std::nullopt);
      } else {  // replace several
        for (Site3 s : RandomSites(rng, 3, diagram == Diagram::kNearest)) {
          changes.emplace_back(s.id, s);
        }
      }
      snapshot = Advance(snapshot, std::move(changes), &free_slots);
      VolumeScanStats stats;
      auto next = UpdateVolume(*volume, snapshot, &stats);
      auto full = ScanVolume(kGrid, diagram, snapshot);
      int differ = 0;
      for (uint32_t k = 0; k < kGrid.depth; ++k) {
        for (uint32_t j = 0; j < kGrid.height; ++j) {
          for (uint32_t i = 0; i < kGrid.width; ++i) {
            if (next->id_at(i, j, k) != full->id_at(i, j, k) ||
                (next->distance_at(i, j, k) != full->distance_at(i, j, k) &&
                 !(std::isnan(next->distance_at(i, j, k)) && std::isnan(full->distance_at(i, j, k))))) {
              ++differ;
            }
          }
        }
        shared_some = shared_some || next->SharesSlice(*volume, k);
      }
      EXPECT_EQ(differ, 0) << "step " << step;
      EXPECT_EQ(next->brick_extremes(), full->brick_extremes()) << "step " << step;
      if (diagram == Diagram::kNearest && kind == 0) {
        EXPECT_LT(stats.bricks, volume->bricks_x() * volume->bricks_y() * volume->bricks_z());
      }
      volume = next;
    }
    if (diagram == Diagram::kNearest) {
      EXPECT_TRUE(shared_some);
    }
  }
}

// Nearest answers from the volume: the site's value is exact, the best value is within the
// bound, outside the box and in scenes with reaches the answer is exact.
TEST(VolumeNearest, WithinItsBound) {
  std::mt19937_64 rng(5);
  for (bool weighted : {false, true}) {
    const auto sites = RandomSites(rng, 30, weighted);
    const auto volume = ScanVolume(kGrid, Diagram::kNearest, Snapshot(sites));
    double widest = 0;
    for (int n = 0; n < 3000; ++n) {
      const Vec3 q = n % 5 == 0 ? Random(rng, -5, 15) : Random(rng, 0, 1) * Vec3(10, 8, 6);
      Real best = INFINITY;
      for (const Site3& s : sites) best = std::min(best, OracleValue(q, s));
      const auto answer = volume->Nearest(q);
      ASSERT_TRUE(answer.has_value());
      if (!std::isfinite(double(best))) {
        EXPECT_FALSE(answer->found);
        continue;
      }
      ASSERT_TRUE(answer->found);
      const Site3& site = *volume->sites().get(answer->site_index);
      const double tol = 1e-9 * (1 + std::abs(double(best)));
      EXPECT_NEAR(answer->distance, double(OracleValue(q, site)), tol);
      EXPECT_LE(answer->distance - double(best), answer->error_bound + tol) << "q " << q.x << "," << q.y << "," << q.z;
      if (!kBox.Contains(q) || volume->error().limited_presence) {
        EXPECT_EQ(answer->error_bound, 0);
      }
      widest = std::max(widest, answer->error_bound);
      const NearestAnswer exact = volume->Refine(q, *answer);
      EXPECT_NEAR(exact.distance, double(best), tol);
    }
    // The bound is about a voxel's diagonal, not the box's.
    EXPECT_LE(widest, 2 * kGrid.voxel_diagonal() * (weighted ? 3 : 1));
  }
}

}  // namespace
}  // namespace gvd

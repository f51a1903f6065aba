// The scene core without GL or gRPC: snapshots, their id maps, slot tables and spatial
// indexes across versions, and the Scene's writers and readers. The oracle is a plain model
// kept here (a std::map of points) with distances by std::hypot, not the production code.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <future>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "render/scene/id_order.h"
#include "render/scene/snapshot.h"
#include "render/scene/scene.h"
#include "tests/support/oracle.h"

namespace gvd {
namespace {

using Model = std::map<std::string, Vec2>;

double Hypot(Vec2 a, Vec2 b) { return std::hypot(a.x - b.x, a.y - b.y); }

// Everything a snapshot says agrees with the model of its version.
void ExpectMatches(const SiteSnapshot& snap, const Model& model, const std::string& what) {
  SCOPED_TRACE(what);
  ASSERT_EQ(snap.size(), model.size());
  ASSERT_EQ(snap.ids().size(), model.size());
  // Ids in order, each to a live slot that holds that site.
  std::vector<std::string> listed;
  snap.ids().ForEachAfter("", [&](const IdMap::Entry& e) {
    listed.push_back(e.id);
    const Site* s = snap.sites().get(e.slot);
    EXPECT_NE(s, nullptr) << e.id;
    if (s) {
      EXPECT_EQ(s->id, e.id);
      Vec2 p = std::get<PointSite>(s->geometry).p;
      EXPECT_EQ(p.x, model.at(e.id).x);
      EXPECT_EQ(p.y, model.at(e.id).y);
    }
    return true;
  });
  std::vector<std::string> expected;
  for (const auto& [id, p] : model) expected.push_back(id);
  EXPECT_EQ(listed, expected);
  size_t live = 0;
  for (uint32_t s = 0; s < snap.sites().size(); ++s) live += snap.sites().get(s) != nullptr;
  EXPECT_EQ(live, model.size());
  for (const auto& [id, p] : model) EXPECT_TRUE(snap.Find(id).has_value()) << id;
  EXPECT_FALSE(snap.Find("absent").has_value());
  // Paging from the middle.
  if (!expected.empty()) {
    const std::string& mid = expected[expected.size() / 2];
    std::vector<std::string> after;
    snap.ids().ForEachAfter(mid, [&](const IdMap::Entry& e) {
      after.push_back(e.id);
      return after.size() < 5;
    });
    std::vector<std::string> want(std::upper_bound(expected.begin(), expected.end(), mid),
                                  expected.end());
    want.resize(std::min<size_t>(want.size(), 5));
    EXPECT_EQ(after, want);
  }
  if (model.empty()) return;
  // The index: exact nearest distances and supersets within a radius.
  std::mt19937_64 rng(snap.version());
  std::uniform_real_distribution<double> u(-0.2, 1.2);
  for (int t = 0; t < 40; ++t) {
    Vec2 q{u(rng), u(rng)};
    double best = INFINITY;
    for (const auto& [id, p] : model) best = std::min(best, Hypot(q, p));
    ExactNearest n = snap.index().Nearest(q);
    ASSERT_TRUE(n.found());
    EXPECT_DOUBLE_EQ(n.distance, best);
    const Site* s = snap.sites().get(static_cast<uint32_t>(n.index));
    ASSERT_NE(s, nullptr);
    EXPECT_DOUBLE_EQ(Hypot(q, model.at(s->id)), best);
    const double r = 0.15;
    std::vector<uint32_t> within;
    snap.index().Within(q, r, &within);
    std::set<std::string> found;
    for (uint32_t slot : within) {
      const Site* w = snap.sites().get(slot);
      ASSERT_NE(w, nullptr) << "a dead slot " << slot;
      found.insert(w->id);
    }
    for (const auto& [id, p] : model) {
      if (Hypot(q, p) <= r) {
        EXPECT_TRUE(found.count(id)) << id;
      }
    }
  }
}

// Random batches of inserts, moves and deletes; every version is kept and checked at the
// end, so older snapshots must survive the making of newer ones unchanged.
TEST(Snapshot, EveryVersionStaysWhatItWas) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<uint32_t> free_slots;
  std::vector<std::shared_ptr<const SiteSnapshot>> snaps{SiteSnapshot::Empty(1)};
  std::vector<Model> models{{}};
  int next = 0;
  for (int step = 0; step < 160; ++step) {
    Model model = models.back();
    std::vector<SiteChange> changes;
    std::set<std::string> touched;
    // Bursts now and then, so that the index's tail overflows into its levels and dead
    // entries pile up until a rebuild.
    int count = step % 25 == 0 ? 700 : 1 + static_cast<int>(rng() % 12);
    for (int c = 0; c < count; ++c) {
      int what = static_cast<int>(rng() % 3);
      if (what == 0 || model.size() < 5) {
        std::string id = "s" + std::to_string(next++);
        model[id] = {u(rng), u(rng)};
        changes.push_back({id, PointSite{model[id]}});
        touched.insert(id);
        continue;
      }
      auto it = model.begin();
      std::advance(it, rng() % model.size());
      std::string id = it->first;
      if (!touched.insert(id).second) continue;
      if (what == 1) {
        model[id] = {u(rng), u(rng)};
        changes.push_back({id, PointSite{model[id]}});
      } else {
        model.erase(id);
        changes.push_back({id, std::nullopt});
      }
    }
    auto base = snaps.back();
    auto snap = Advance(base, std::move(changes), &free_slots);
    EXPECT_EQ(snap->version(), base->version() + 1);
    // The slots that differ are exactly those of the ids touched.
    std::set<uint32_t> expected_slots, diffed;
    for (const std::string& id : touched) {
      if (auto s = base->Find(id)) expected_slots.insert(*s);
      if (auto s = snap->Find(id)) expected_slots.insert(*s);
    }
    SlotTable::Diff(base->sites(), snap->sites(),
                    [&](uint32_t s, const Site*, const Site*) { diffed.insert(s); });
    EXPECT_EQ(diffed, expected_slots) << "step " << step;
    snaps.push_back(snap);
    models.push_back(std::move(model));
  }
  for (size_t v = 0; v < snaps.size() && !HasFailure(); ++v) {
    ExpectMatches(*snaps[v], models[v], "version " + std::to_string(snaps[v]->version()));
  }
}

// Ids sorted for the id map in std::string's order: bytes compared unsigned, a prefix first,
// whatever the bytes (NULs, bytes above 0x7f) and however long the shared prefix.
TEST(Snapshot, IdsSortInStringOrder) {
  std::mt19937_64 rng(12);
  const std::string alphabet = std::string("a\0\x7f\x80\xff", 5) + "0";
  std::vector<std::string> ids = {"", std::string(1, '\0'), std::string(9, '\0'), "abcdefgh",
                                  "abcdefg", "abcdefgh\x01", "abcdefghi", "site-0000001",
                                  "site-0000010", "site-000001"};
  for (int k = 0; k < 3000; ++k) {
    std::string id = rng() % 2 ? "prefix-x" : "";
    for (size_t n = rng() % 12; n > 0; --n) id += alphabet[rng() % alphabet.size()];
    ids.push_back(id);
  }
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  std::vector<IdMap::Change> changes;
  for (size_t k = 0; k < ids.size(); ++k) changes.emplace_back(ids[k], static_cast<uint32_t>(k));
  std::shuffle(changes.begin(), changes.end(), rng);
  SortById(&changes);
  ASSERT_EQ(changes.size(), ids.size());
  for (size_t k = 0; k < ids.size(); ++k) {
    EXPECT_EQ(changes[k].first, ids[k]) << k;
    EXPECT_EQ(changes[k].second, k) << "an id and its slot stay together";
  }
}

// Equal ids keep their positions' order (the store's last put of an id is written last).
TEST(Snapshot, EqualIdsKeepTheirOrder) {
  std::mt19937_64 rng(14);
  std::vector<std::string> ids;
  for (int k = 0; k < 2000; ++k) ids.push_back("id-" + std::to_string(rng() % 300));
  const std::vector<uint32_t> order =
      IdOrder(ids.size(), [&](size_t k) -> std::string_view { return ids[k]; });
  ASSERT_EQ(order.size(), ids.size());
  std::vector<uint32_t> expected(ids.size());
  for (uint32_t k = 0; k < ids.size(); ++k) expected[k] = k;
  std::stable_sort(expected.begin(), expected.end(),
                   [&](uint32_t a, uint32_t b) { return ids[a] < ids[b]; });
  EXPECT_EQ(order, expected);
}

// A snapshot's ink (the summed length of its sites' segments) across puts, replacements and
// removals of segments and polylines, against the sum over a model, by std::hypot.
TEST(Snapshot, InkFollowsEveryChange) {
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<uint32_t> free_slots;
  auto snap = SiteSnapshot::Empty(1);
  std::map<std::string, std::vector<Vec2>> model;  // each site's chain of points
  for (int step = 0; step < 200; ++step) {
    std::vector<SiteChange> changes;
    std::set<std::string> touched;
    for (int c = 0; c < 1 + static_cast<int>(rng() % 6); ++c) {
      const std::string id = "s" + std::to_string(rng() % 40);
      if (!touched.insert(id).second) continue;
      if (rng() % 4 == 0) {
        model.erase(id);
        changes.push_back({id, std::nullopt});
        continue;
      }
      std::vector<Vec2> chain(1 + rng() % 5);  // one point is a point site
      for (Vec2& p : chain) p = {u(rng), u(rng)};
      model[id] = chain;
      if (chain.size() == 1) {
        changes.push_back({id, PointSite{chain[0]}});
      } else if (chain.size() == 2) {
        changes.push_back({id, SegmentSite{chain[0], chain[1]}});
      } else {
        changes.push_back({id, PolylineSite{chain}});
      }
    }
    snap = Advance(snap, std::move(changes), &free_slots);
    double want = 0;
    for (const auto& [id, chain] : model) {
      for (size_t k = 0; k + 1 < chain.size(); ++k) want += Hypot(chain[k], chain[k + 1]);
    }
    ASSERT_NEAR(snap->ink(), want, 1e-9) << "step " << step;
  }
  model.clear();
  std::vector<SiteChange> all;
  snap->ids().ForEachAfter("", [&](const IdMap::Entry& e) {
    all.push_back({e.id, std::nullopt});
    return true;
  });
  EXPECT_EQ(Advance(snap, std::move(all), &free_slots)->ink(), 0);
}

// A table's least weights, kept per chunk as sites come and go, against the minimum over a
// plain model of its slots: few distinct weights (so that ties at the least are common and
// removing one of them must not lose the others), removals of the least, emptied chunks,
// and copies whose changes must not reach the original.
TEST(SlotTable, LeastWeightsFollowEveryChange) {
  std::mt19937_64 rng(12);
  const double kWeights[] = {0.5, 1, 1, 2, 3.25};
  std::map<uint32_t, std::pair<double, double>> model;  // slot -> (multiplicative, additive)
  SlotTable table;
  auto check = [](const SlotTable& t, const std::map<uint32_t, std::pair<double, double>>& m) {
    double least_m = INFINITY, least_a = INFINITY;
    for (const auto& [slot, w] : m) {
      least_m = std::min(least_m, w.first);
      least_a = std::min(least_a, w.second);
    }
    LeastWeights got = t.least();
    ASSERT_EQ(got.multiplicative, least_m);
    ASSERT_EQ(got.additive, least_a);
  };
  const uint32_t kSlots = SlotTable::kBlockSlots + 3 * SlotTable::kChunk;  // two blocks
  for (int step = 0; step < 20000; ++step) {
    const uint32_t slot = rng() % kSlots;
    if (rng() % 3 == 0) {
      table.Set(slot, std::shared_ptr<const Site>());
      model.erase(slot);
    } else {
      Site site{std::to_string(slot), PointSite{{0, 0}}};
      site.multiplicative = kWeights[rng() % 5];
      site.additive = kWeights[rng() % 5] - 0.5;
      model[slot] = {site.multiplicative, site.additive};
      table.Set(slot, std::make_shared<const Site>(site));
    }
    if (step % 97 == 0) {
      ASSERT_NO_FATAL_FAILURE(check(table, model));
    }
    if (step == 10000) {
      // A copy goes its own way; the original keeps its least.
      SlotTable copy = table;
      auto copy_model = model;
      for (uint32_t s = 0; s < kSlots; ++s) copy.Set(s, std::shared_ptr<const Site>());
      ASSERT_NO_FATAL_FAILURE(check(copy, {}));
      ASSERT_NO_FATAL_FAILURE(check(table, copy_model));
    }
  }
  // Emptied one chunk after another, least first.
  std::vector<uint32_t> by_weight;
  for (const auto& [slot, w] : model) by_weight.push_back(slot);
  std::sort(by_weight.begin(), by_weight.end(), [&](uint32_t a, uint32_t b) {
    return model[a] < model[b];
  });
  for (uint32_t slot : by_weight) {
    table.Set(slot, std::shared_ptr<const Site>());
    model.erase(slot);
    ASSERT_NO_FATAL_FAILURE(check(table, model));
  }
}

// The table's record of where a plain point is (what raster lookups read instead of the site)
// against the sites themselves: every kind and variant, replaced and freed slots, two blocks,
// and a copy whose changes must not reach the original.
TEST(SlotTable, PointRecordsFollowTheSites) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-2, 2);
  const uint32_t kSlots = SlotTable::kBlockSlots + 2 * SlotTable::kChunk;
  std::map<uint32_t, std::shared_ptr<const Site>> model;
  auto check = [](const SlotTable& t, const std::map<uint32_t, std::shared_ptr<const Site>>& m,
                  uint32_t slots) {
    for (uint32_t s = 0; s < std::min(slots, t.size()); ++s) {
      auto it = m.find(s);
      const Site* site = it == m.end() ? nullptr : it->second.get();
      ASSERT_EQ(t.get(s), site) << "slot " << s;
      Vec2 p = t.point(s);
      const bool plain_point = site != nullptr && std::holds_alternative<PointSite>(site->geometry) &&
                               site->additive == 0 && site->multiplicative == 1 &&
                               std::isinf(site->max_distance);
      if (plain_point) {
        ASSERT_EQ(p.x, std::get<PointSite>(site->geometry).p.x) << "slot " << s;
        ASSERT_EQ(p.y, std::get<PointSite>(site->geometry).p.y) << "slot " << s;
      } else {
        ASSERT_TRUE(std::isnan(p.x) && std::isnan(p.y)) << "slot " << s;
      }
    }
  };
  SlotTable table;
  for (int step = 0; step < 6000; ++step) {
    const uint32_t slot = rng() % kSlots;
    std::shared_ptr<const Site> site;
    if (rng() % 4 != 0) {
      Site x{std::to_string(slot), PointSite{{u(rng), u(rng)}}};
      switch (rng() % 5) {
        case 0: x.additive = 0.5; break;
        case 1: x.multiplicative = 2; break;
        case 2: x.max_distance = 1; break;
        case 3: x.geometry = SegmentSite{{0, 0}, {u(rng), u(rng)}}; break;
        default: break;
      }
      site = std::make_shared<const Site>(x);
      model[slot] = site;
    } else {
      model.erase(slot);
    }
    table.Set(slot, site);
    if (step % 211 == 0) {
      ASSERT_NO_FATAL_FAILURE(check(table, model, kSlots));
    }
    if (step == 3000) {
      SlotTable copy = table;
      auto copy_model = model;
      for (uint32_t s = 0; s < kSlots; s += 7) {
        copy.Set(s, std::make_shared<const Site>(Site{"c", PointSite{{9, 9}}}));
        copy_model[s] = copy.ptr(s);
      }
      ASSERT_NO_FATAL_FAILURE(check(copy, copy_model, kSlots));
      ASSERT_NO_FATAL_FAILURE(check(table, model, kSlots));
    }
  }
  ASSERT_NO_FATAL_FAILURE(check(table, model, kSlots));
}

TEST(Snapshot, FreedSlotsAreTakenAgainAndAbandonGivesThemBack) {
  std::vector<uint32_t> free_slots;
  auto a = Advance(SiteSnapshot::Empty(1),
                   {{"a", PointSite{{0, 0}}}, {"b", PointSite{{1, 0}}}, {"c", PointSite{{2, 0}}}},
                   &free_slots);
  const uint32_t slot_b = *a->Find("b");
  auto b = Advance(a, {{"b", std::nullopt}}, &free_slots);
  EXPECT_EQ(free_slots, std::vector<uint32_t>{slot_b});
  {
    SnapshotBuilder abandoned(b, &free_slots);
    abandoned.Put(Site{"d", PointSite{{3, 0}}});
    EXPECT_TRUE(free_slots.empty());
    abandoned.Abandon();
  }
  EXPECT_EQ(free_slots, std::vector<uint32_t>{slot_b});
  auto c = Advance(b, {{"d", PointSite{{3, 0}}}}, &free_slots);
  EXPECT_EQ(*c->Find("d"), slot_b);
  EXPECT_EQ(c->sites().size(), 3u);
  // The older snapshots still hold what they held.
  EXPECT_EQ(a->sites().get(slot_b)->id, "b");
  EXPECT_EQ(b->sites().get(slot_b), nullptr);
  ExpectMatches(*c, {{"a", {0, 0}}, {"c", {2, 0}}, {"d", {3, 0}}}, "after reuse");
}

SceneSettings Settings() {
  SceneSettings s;
  s.id = "core";
  s.grid = Grid{{0, 0, 1, 1}, 64, 64};
  s.eps = s.grid.pixel_size();
  return s;
}

// A refused write (over the site limit, or failing to persist) changes nothing.
TEST(SceneCore, RefusedWritesChangeNothing) {
  Scene scene(Settings());
  ASSERT_TRUE(scene.Upsert({{"a", PointSite{{0.1, 0.1}}}, {"b", PointSite{{0.9, 0.9}}}}, 10).ok());
  auto before = scene.snapshot();
  auto over = scene.Upsert({{"c", PointSite{{0.5, 0.5}}}, {"d", PointSite{{0.4, 0.5}}}}, 3);
  EXPECT_EQ(over.status().code(), absl::StatusCode::kResourceExhausted);
  auto failed = scene.Upsert({{"a", PointSite{{0.5, 0.5}}}}, 10, [](const ChangeSet&) {
    return absl::UnavailableError("disk");
  });
  EXPECT_EQ(failed.status().code(), absl::StatusCode::kUnavailable);
  auto missing = scene.Delete({"a", "zz"});
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kNotFound);
  EXPECT_NE(missing.status().message().find("ids[1] \"zz\""), std::string::npos);
  EXPECT_EQ(scene.snapshot(), before);
  EXPECT_EQ(scene.version(), 2u);
  Scene::Picked p = scene.Pick({0.12, 0.1}, INFINITY);
  ASSERT_TRUE(p.found);
  EXPECT_EQ(p.site->id, "a");
  // A bulk write, whose snapshot is built while the store works, refused by the store (after
  // a deletion left a slot free for it to take).
  ASSERT_TRUE(scene.Delete({"b"}).ok());
  before = scene.snapshot();
  std::vector<Site> bulk;
  for (int i = 0; i < 5000; ++i) bulk.push_back({"bulk" + std::to_string(i), PointSite{{0.5, 0.5}}});
  bool stored = false;
  auto refused = scene.Upsert(bulk, 10000, [&](const ChangeSet& c) {
    stored = c.put_count() == bulk.size();
    return absl::UnavailableError("disk");
  });
  EXPECT_TRUE(stored);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_EQ(scene.snapshot(), before);
  // The slot it took was given back: the next site takes it.
  ASSERT_TRUE(scene.Upsert({{"c", PointSite{{0.3, 0.3}}}}, 10).ok());
  EXPECT_EQ(scene.snapshot()->Find("c"), std::optional<uint32_t>(1));
  EXPECT_EQ(scene.snapshot()->size(), 2u);
}

// A caller waiting for a frame holds the renders at a caller's priority (RenderWait) until
// it is resumed, cancelled or failed; a caller waiting for a snapshot does not.
TEST(SceneCore, AFramesWaiterHoldsRendersAtACallersPriority) {
  Scene scene(Settings());
  ASSERT_TRUE(scene.Upsert({{"a", PointSite{{0.25, 0.5}}}}, 10).ok());
  auto emptied = scene.Delete({"a"});
  ASSERT_TRUE(emptied.ok());
  const int before = RenderWait::held();
  int resumed = 0;
  scene.WhenRendered(*emptied, [&](auto frame) { resumed += frame.ok(); });
  EXPECT_EQ(RenderWait::held(), before + 1);
  const uint64_t committed = scene.WhenCommitted(*emptied + 1, [](auto) {});
  const uint64_t cancelled = scene.WhenRendered(*emptied + 1, [](auto) {});
  EXPECT_EQ(RenderWait::held(), before + 2);
  scene.Cancel(committed, absl::CancelledError("gone"));
  scene.Cancel(cancelled, absl::CancelledError("gone"));
  EXPECT_EQ(RenderWait::held(), before + 1);
  scene.Publish(Frame::Empty(Settings().grid, Settings().eps, scene.snapshot()));
  EXPECT_EQ(resumed, 1);
  EXPECT_EQ(RenderWait::held(), before);
  scene.WhenRendered(*emptied + 1, [](auto) {});
  EXPECT_EQ(RenderWait::held(), before + 1);
  scene.FailWaiters(absl::UnavailableError("stopping"));
  EXPECT_EQ(RenderWait::held(), before);
}

// A durable commit holds only the writer lock: readers (and the render thread, which reads
// the same snapshot) go on while it is under way and see the version before it.
TEST(SceneCore, ReadersDoNotWaitForACommit) {
  Scene scene(Settings());
  ASSERT_TRUE(scene.Upsert({{"a", PointSite{{0.25, 0.5}}}}, 10).ok());
  bool read_during_commit = false;
  auto v = scene.Upsert({{"b", PointSite{{0.75, 0.5}}}}, 10, [&](const ChangeSet& c) {
    EXPECT_EQ(c.version, 3u);
    auto reader = std::async(std::launch::async, [&] {
      std::vector<Scene::ExactAnswer> answers;
      uint64_t version = scene.NearestExact({{0.8, 0.5}}, &answers);
      Scene::SitePage page = scene.ListSites("", 10);
      return version == 2 && answers[0].site_id == "a" && page.sites.size() == 1 &&
             scene.snapshot()->version() == 2;
    });
    if (reader.wait_for(std::chrono::seconds(30)) != std::future_status::ready) {
      ADD_FAILURE() << "a reader waited for the commit";
      std::abort();  // the reader is stuck behind this very callback
    }
    read_during_commit = reader.get();
    return absl::OkStatus();
  });
  ASSERT_TRUE(v.ok());
  EXPECT_TRUE(read_during_commit);
  std::vector<Scene::ExactAnswer> answers;
  EXPECT_EQ(scene.NearestExact({{0.8, 0.5}}, &answers), 3u);
  EXPECT_EQ(answers[0].site_id, "b");
}

// Exact answers in scenes with weights, max_distance and sides come from the index, bounded
// through the least weights by the value found at the point (here, with no frame, the value
// of the site nearest by distance, which weights often beat), and in FARTHEST scenes from
// every site: against the oracle, at points in and around the window.
TEST(SceneCore, ExactAnswersWithWeightsBoundsAndSides) {
  std::mt19937_64 rng(41);
  std::uniform_real_distribution<double> u(-0.3, 1.3), w(0, 1);
  for (Diagram diagram : {Diagram::kNearest, Diagram::kFarthest}) {
    SceneSettings settings = Settings();
    settings.diagram = diagram;
    Scene scene(settings);
    std::vector<Site> sites;
    for (int i = 0; i < 400; ++i) {
      Site s{"s" + std::to_string(i), PointSite{{u(rng), u(rng)}}};
      if (i % 7 == 0) {
        const Vec2 c{u(rng), u(rng)};
        s.geometry = PolygonSite{{c, c + Vec2{0.1, 0.02}, c + Vec2{0.05, 0.12}},
                                 static_cast<Side>(i % 3)};
      }
      s.multiplicative = 0.3 + 3 * w(rng);
      s.additive = i % 3 == 0 ? 0.2 * w(rng) : 0;
      if (i % 5 == 0) s.max_distance = 0.05 + 0.3 * w(rng);
      sites.push_back(s);
    }
    ASSERT_TRUE(scene.Upsert(sites, 1000).ok());
    std::vector<Vec2> points;
    for (int k = 0; k < 3000; ++k) points.push_back({u(rng), u(rng)});
    std::vector<Scene::ExactAnswer> answers;
    ASSERT_NE(scene.NearestExact(points, &answers), 0u);
    int failures = 0;
    for (size_t k = 0; k < points.size() && failures < 5; ++k) {
      const oracle::Best truth = oracle::BestSite(points[k], sites, diagram);
      const Scene::ExactAnswer& a = answers[k];
      const bool ok =
          a.found == truth.found &&
          (!truth.found ||
           std::abs(a.distance - truth.value) <= oracle::Tolerance(points[k], truth.value, 4));
      if (!ok) {
        ++failures;
        ADD_FAILURE() << (diagram == Diagram::kNearest ? "nearest" : "farthest") << " point "
                      << k << ": " << a.site_id << " at " << a.distance << ", truth "
                      << (truth.found ? sites[truth.index].id : "none") << " at " << truth.value;
      }
    }
  }
}

// Pages of ListSites cover every id once, in order, across the leaves of the id map.
TEST(SceneCore, ListSitesPagesInIdOrder) {
  Scene scene(Settings());
  std::vector<Site> sites;
  std::vector<std::string> ids;
  for (int i = 0; i < 2000; ++i) {
    std::string id = "id" + std::to_string(i * 7919 % 2000);
    ids.push_back(id);
    sites.push_back({id, PointSite{{(i % 50) / 50.0, (i / 50) / 40.0}}});
  }
  ASSERT_TRUE(scene.Upsert(std::move(sites), 5000).ok());
  std::sort(ids.begin(), ids.end());
  std::vector<std::string> paged;
  std::string after;
  for (int pages = 0; pages < 100; ++pages) {
    Scene::SitePage page = scene.ListSites(after, 333);
    for (const Site& s : page.sites) paged.push_back(s.id);
    if (page.last_id.empty()) break;
    after = page.last_id;
  }
  EXPECT_EQ(paged, ids);
}

}  // namespace
}  // namespace gvd

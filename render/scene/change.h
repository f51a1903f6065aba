// A change of a scene, as the scene core makes it durable (BasicScene::Persist) and publishes
// it (BasicScene::Apply): the sites it puts, the ids it removes and the version it brings the
// scene to. The store engines (server/store/) write it; the scene core knows no store.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <variant>

#include "render/kernel/site2.h"
#include "render/kernel/site3.h"

namespace gvd {

// When a commit counts as made: kSync, durable before the call returns (it survives a power
// loss); kRelaxed, written to the store before the call returns (it survives a crash of the
// server) and durable a bounded time later (the engine's: SqliteStore's flusher, the
// database's WAL writer), for interactive edits that would otherwise wait on a disk flush
// each.
enum class Durability : uint8_t { kSync, kRelaxed };

// The sites a change puts, of either dimension: a 2D scene's or a 3D scene's. A view.
template <class S>
using SitesPut = std::span<const std::shared_ptr<const S>>;
using AnySitesPut = std::variant<SitesPut<Site>, SitesPut<Site3>>;

// One accepted write of one scene: the sites it puts (inserted or replaced) and the ids it
// removes, and the version it brings the scene to. A view: valid during the call it is
// passed to.
struct ChangeSet {
  std::string_view scene_id;
  uint64_t version = 0;  // the version it brings the scene to
  AnySitesPut put;       // of the scene's own dimension
  std::span<const std::string> removed;
  // The version it follows: 0 for version - 1 (a write); lower for the net change of
  // several versions a follower read (SceneChanges).
  uint64_t follows = 0;
  // The incarnation of the scene it was made for (StoredScene::incarnation): the engine
  // refuses it (ABORTED) when the scene's id now names another one. 0: not checked.
  uint64_t incarnation = 0;
  // The digest of the sites the writer holds at base() (server/store/digest.h): an engine
  // that keeps digests refuses the change (ABORTED) when its own differs, for then it holds
  // other sites at that version (it went back in time and was written again). Unset: not
  // checked.
  std::optional<uint64_t> base_digest;
  Durability durability = Durability::kSync;

  uint64_t base() const { return follows != 0 ? follows : version - 1; }

  // The sites put, when they are S's (Site or Site3); else none.
  template <class S>
  SitesPut<S> Put() const {
    const auto* sites = std::get_if<SitesPut<S>>(&put);
    return sites ? *sites : SitesPut<S>();
  }
  // Whether the sites put are of the other dimension than S's (a change that cannot apply).
  template <class S>
  bool PutsOther() const {
    return !std::holds_alternative<SitesPut<S>>(put) &&
           std::visit([](const auto& sites) { return !sites.empty(); }, put);
  }
  size_t put_count() const {
    return std::visit([](const auto& sites) { return sites.size(); }, put);
  }
};

}  // namespace gvd

// What the store engines share: how a site row's bytes become a site of its scene's kind,
// and how long a scene's tombstones are kept.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <type_traits>
#include <variant>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "render/scene/codec.h"
#include "server/store/store.h"

namespace gvd {

// A removed site's row keeps its id and the version that removed it, with no bytes.
inline bool IsTombstone(std::string_view site_bytes) { return site_bytes.empty(); }

// How much of a scene's history is kept: its tombstones of versions up to its version less
// `versions` are dropped (and its horizon moves up) by the commit of every `every`-th
// version. A follower further behind reads the scene's whole state.
struct Retention {
  uint64_t versions = 4096;
  uint64_t every = 64;
  bool CompactsAt(uint64_t version) const {
    return version > versions && version % every == 0;
  }
  uint64_t HorizonAt(uint64_t version) const { return version - versions; }
};

// The refusal of a change set whose scene is at `stored` (of incarnation `incarnation`, its
// sites of digest `digest` when the engine keeps digests), not at the version it follows, of
// the incarnation it was made for or with the sites it was made on.
inline absl::Status StaleChange(const ChangeSet& changes, uint64_t stored, uint64_t incarnation,
                                std::optional<uint64_t> digest = std::nullopt) {
  const std::string scene(changes.scene_id);
  if (changes.incarnation != 0 && changes.incarnation != incarnation) {
    return absl::AbortedError(absl::StrCat(
        "scene \"", scene,
        "\" was deleted and made again by another server since this change was made"));
  }
  if (stored < changes.base()) {
    return absl::AbortedError(absl::StrCat(
        "scene \"", scene, "\" is at version ", stored, " in the store, behind version ",
        changes.base(), " that this server holds: the store went back in time (restored from "
        "a copy, or failed over to a standby that had not received the last commits), and "
        "this server reloads the scene from it"));
  }
  if (stored == changes.base() && digest && changes.base_digest && *digest != *changes.base_digest) {
    return absl::AbortedError(absl::StrCat(
        "scene \"", scene, "\" holds other sites at version ", stored,
        " in the store than this server does: the store went back in time and was written "
        "again since, and this server reloads the scene from it"));
  }
  return absl::AbortedError(absl::StrCat(
      "scene \"", scene, "\" is at version ", stored, " in the store, not at ",
      changes.base(), ": another server wrote to it first"));
}

// Decodes a site row of `settings`' scene into `sites` (AnySites or AnySharedSites), whose
// alternative it sets to the scene's dimension. DATA_LOSS naming the scene when its bytes
// are damaged.
template <class T>
void Add(std::vector<T>* out, T site) {
  out->push_back(std::move(site));
}
template <class T>
void Add(std::vector<std::shared_ptr<const T>>* out, T site) {
  out->push_back(std::make_shared<const T>(std::move(site)));
}
template <class AnyOf>
absl::Status DecodeInto(const SceneSettings& settings, std::string_view bytes, AnyOf* sites) {
  if (settings.three_d() && sites->index() != 1) sites->template emplace<1>();
  return std::visit(
      [&](auto& out) -> absl::Status {
        using T = std::decay_t<decltype(out)>;
        using S = std::conditional_t<std::is_same_v<T, std::vector<Site3>> ||
                                         std::is_same_v<T, SharedSites<Site3>>,
                                     Site3, Site>;
        auto site = DecodeSite<S>(bytes);
        if (!site.ok()) {
          return absl::DataLossError(absl::StrCat("store: a site of scene \"", settings.id,
                                                  "\": ", site.status().message()));
        }
        Add(&out, std::move(*site));
        return absl::OkStatus();
      },
      *sites);
}

}  // namespace gvd

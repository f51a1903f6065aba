// The core's own byte form of sites and scene settings, as stores keep them: compact, exact
// (doubles bit for bit) and versioned by a leading format byte. Decoding checks the
// structure (lengths, tags, enum values) and reports damage as DATA_LOSS; it does not judge
// the values again, which were checked when the site was accepted.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "render/scene/settings.h"
#include "render/kernel/site2.h"
#include "render/kernel/site3.h"

namespace gvd {

// A site of either dimension (Site, or Site3: a mesh is stored as its vertices and
// triangles, and its edge tables and tree are made again when it is read). DecodeSite<S>
// reads S's byte form only: another kind's is DATA_LOSS.
std::string EncodeSite(const Site& site);
std::string EncodeSite(const Site3& site);
template <class S>
absl::StatusOr<S> DecodeSite(std::string_view bytes);
template <>
absl::StatusOr<Site> DecodeSite<Site>(std::string_view bytes);
template <>
absl::StatusOr<Site3> DecodeSite<Site3>(std::string_view bytes);

std::string EncodeSettings(const SceneSettings& settings);

// A pack: the sites of one change set in one record, each entry the site's id and its
// EncodeSite bytes, both written as the codec writes strings (a 32-bit length, then the
// bytes), in the order appended.
void AppendToPack(const Site& site, std::string* pack);
void AppendToPack(const Site3& site, std::string* pack);
struct PackEntry {
  std::string_view id, site;  // into the pack
};
// A pack's entries in order; DATA_LOSS when its framing is damaged.
absl::StatusOr<std::vector<PackEntry>> PackEntries(std::string_view pack);
absl::StatusOr<SceneSettings> DecodeSettings(std::string_view bytes);

}  // namespace gvd

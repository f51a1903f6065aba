// What a scene's sites are, in eight bytes: how replicas tell that their copy of a scene and
// the store's hold the same sites at a version, so that a store that went back in time (a
// restore, a failover that lost commits) and was written again is not taken for the history
// a replica holds.
//
// A site's digest is the first eight bytes, big-endian, of the SHA-256 of its stored bytes
// (EncodeSite, render/scene/codec.h); a scene's digest is the XOR of its live sites' digests
// (0 for no sites), so a change moves it by the digests of the sites it puts and of those it
// replaces or removes. PostgreSQL computes the same from a row's bytes:
// kSqlSiteDigest.
#pragma once

#include <cstdint>
#include <string_view>

#include "render/kernel/site2.h"
#include "render/kernel/site3.h"

namespace gvd {

uint64_t SiteDigest(std::string_view stored_bytes);
uint64_t SiteDigest(const Site& site);
uint64_t SiteDigest(const Site3& site);

// SiteDigest of the bytea column `site`, as a PostgreSQL bigint (the same 64 bits).
inline constexpr const char* kSqlSiteDigest =
    "('x' || encode(substr(sha256(site), 1, 8), 'hex'))::bit(64)::int8";

}  // namespace gvd

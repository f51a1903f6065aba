// Sites: the API's Site into a site of the scene's dimension (checked: geometry set with
// enough points, coordinates finite, weights and max_distance in range) and back; the
// requests that write them (their ids, their durability).
#pragma once

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "gvd/v1/voronoi.pb.h"
#include "render/kernel/site2.h"
#include "render/kernel/site3.h"
#include "render/scene/change.h"
#include "server/app/convert/common.h"
#include "server/app/limits.h"

namespace gvd {

// One site of a scene of the output's dimension (`field` names it in messages, e.g.
// "sites[3]"): a 2D scene's (Bezier curves flattened here), or a 3D scene's (points and
// segments with z, triangles, and meshes checked by MakeMesh against
// --max-triangles-per-mesh); weights as in either.
absl::Status ToSite(const v1::Site& site, const FieldPath& field, const ServerLimits& limits,
                    Site* out);
absl::Status ToSite(const v1::Site& site, const FieldPath& field, const ServerLimits& limits,
                    Site3* out);

// Every site of the request, as SiteT (Site or Site3): ids non-empty, short and distinct,
// each as ToSite.
template <class SiteT>
absl::Status ToSites(const v1::UpsertSitesRequest& request, const ServerLimits& limits,
                     std::vector<SiteT>* sites);

// A write's `durability` field: SYNC when unspecified.
absl::Status ToDurability(v1::Durability durability, Durability* out);

// Checks ids non-empty and distinct.
absl::Status ToSiteIds(const v1::DeleteSitesRequest& request, const ServerLimits& limits,
                       std::vector<std::string>* ids);

void ToProto(const Site& site, v1::Site* out);
void ToProto(const Site3& site, v1::Site* out);

}  // namespace gvd

#include "server/app/legacy_records.h"

#include "server/app/convert/scenes.h"
#include "server/app/convert/sites.h"

namespace gvd {

SqliteStore::Legacy LegacyRecords(const ServerLimits& limits) {
  auto refused = [](const absl::Status& s) { return absl::DataLossError(s.message()); };
  return {
      [limits, refused](std::string_view bytes) -> absl::StatusOr<SceneSettings> {
        v1::CreateSceneRequest request;
        if (!request.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) {
          return absl::DataLossError("unreadable CreateSceneRequest");
        }
        SceneSettings settings;
        if (auto s = ToSceneSettings(request, limits, &settings); !s.ok()) return refused(s);
        return settings;
      },
      [limits, refused](std::string_view bytes) -> absl::StatusOr<Site> {
        v1::Site message;
        if (!message.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) {
          return absl::DataLossError("unreadable Site");
        }
        Site site;
        if (auto s = ToSite(message, "site", limits, &site); !s.ok()) return refused(s);
        if (message.id().empty()) return absl::DataLossError("a site without an id");
        return site;
      },
  };
}

}  // namespace gvd

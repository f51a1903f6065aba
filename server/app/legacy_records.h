// The records of a database written by an earlier release, which kept request messages
// (CreateSceneRequest, Site): read and checked as requests are checked, so that
// SqliteStore::Open converts such a database once, at the server's start.
#pragma once

#include "server/app/limits.h"
#include "server/store/sqlite_store.h"

namespace gvd {

SqliteStore::Legacy LegacyRecords(const ServerLimits& limits);

}  // namespace gvd

// Structured logs: one logfmt line per event on stderr, e.g.
//   ts=2026-11-21T10:00:00.123Z level=info event=listening address=127.0.0.1:50051
// Thread-safe.
#pragma once

#include <initializer_list>
#include <string>
#include <string_view>
#include <utility>

namespace gvd {

enum class LogLevel { kDebug = 0, kInfo = 1, kWarn = 2, kError = 3 };

// Parses debug, info, warn or error. Returns false for anything else.
bool ParseLogLevel(std::string_view name, LogLevel* level);
void SetLogLevel(LogLevel level);
bool LogEnabled(LogLevel level);

using LogField = std::pair<std::string_view, std::string>;

// Writes one line if `level` is enabled; values are quoted when they need it.
void Log(LogLevel level, std::string_view event, std::initializer_list<LogField> fields = {});

// A number as logs and error messages write it: the shortest form that reads back as `v`
// (up to 17 significant digits), NaN, inf, -inf.
std::string FormatNumber(double v);

}  // namespace gvd

#include "server/app/memory.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <cctype>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/strip.h"

namespace gvd {

uint64_t MemoryBudget::used() const {
  std::lock_guard<std::mutex> lock(mu_);
  return in_use_() + reserved_;
}

absl::Status MemoryBudget::Reserve(uint64_t bytes, const std::string& what) {
  std::lock_guard<std::mutex> lock(mu_);
  const uint64_t used = in_use_() + reserved_;
  if (bytes > limit_ || used > limit_ - bytes) {
    return absl::ResourceExhaustedError(absl::StrCat(
        what, " needs ", FormatBytes(bytes), "; the memory budget (--max-memory) is ",
        FormatBytes(limit_), ", of which ", FormatBytes(std::min(used, limit_)), " is in use"));
  }
  reserved_ += bytes;
  return absl::OkStatus();
}

void MemoryBudget::Release(uint64_t bytes) {
  std::lock_guard<std::mutex> lock(mu_);
  reserved_ -= std::min(bytes, reserved_);
}

std::optional<uint64_t> ParseBytes(const std::string& whole) {
  const absl::string_view text = whole;
  size_t digits = 0;
  while (digits < text.size() && (std::isdigit(static_cast<unsigned char>(text[digits])) || text[digits] == '.')) {
    ++digits;
  }
  double number = 0;
  if (digits == 0 || !absl::SimpleAtod(text.substr(0, digits), &number)) return std::nullopt;
  absl::string_view unit = text.substr(digits);
  double scale = 1;
  if (!unit.empty()) {
    const absl::string_view units = "kMGT";
    const size_t power = units.find(unit[0] == 'K' ? 'k' : unit[0]);
    if (power == absl::string_view::npos) return std::nullopt;
    scale = std::pow(1024.0, double(power + 1));
    unit.remove_prefix(1);
    absl::ConsumePrefix(&unit, "i");
    absl::ConsumePrefix(&unit, "B");
    if (!unit.empty()) return std::nullopt;
  }
  const double bytes = std::floor(number * scale);
  if (!(bytes >= 1) || bytes > 1.8e19) return std::nullopt;
  return static_cast<uint64_t>(bytes);
}

namespace {

// A limit in bytes read from a cgroup file, or nullopt ("max", missing, or absurdly large:
// cgroup v1 writes 2^63 rounded to pages for none).
std::optional<uint64_t> LimitIn(const std::string& path) {
  std::ifstream in(path);
  std::string word;
  uint64_t v = 0;
  if (!(in >> word) || !absl::SimpleAtoi(word, &v) || v == 0 || v >= (uint64_t{1} << 60)) {
    return std::nullopt;
  }
  return v;
}

}  // namespace

uint64_t DefaultMaxMemory(const std::string& cgroup_root, std::string* source) {
  std::optional<uint64_t> limit;
  auto consider = [&](std::optional<uint64_t> v) {
    if (v && (!limit || *v < *limit)) limit = v;
  };
  // cgroup v2: this process's own group, and the namespace's root (a container's).
  std::ifstream self("/proc/self/cgroup");
  for (std::string line; std::getline(self, line);) {
    absl::string_view path = line;
    if (absl::ConsumePrefix(&path, "0::")) {
      consider(LimitIn(absl::StrCat(cgroup_root, path, "/memory.max")));
    }
  }
  consider(LimitIn(cgroup_root + "/memory.max"));
  consider(LimitIn(cgroup_root + "/memory/memory.limit_in_bytes"));  // cgroup v1
  if (limit) {
    *source = "cgroup";
  } else {
    *source = "physical memory";
    limit = uint64_t(sysconf(_SC_PHYS_PAGES)) * uint64_t(sysconf(_SC_PAGE_SIZE));
  }
  return *limit / 4 * 3;
}

std::string FormatBytes(uint64_t bytes) {
  constexpr const char* kUnits[] = {"KiB", "MiB", "GiB", "TiB"};
  if (bytes < 1024) return absl::StrCat(bytes, " bytes");
  double v = double(bytes) / 1024;
  int unit = 0;
  while (v >= 1024 && unit < 3) {
    v /= 1024;
    ++unit;
  }
  return absl::StrFormat("%.4g %s", v, kUnits[unit]);
}

}  // namespace gvd

#include "server/app/auth.h"

#include <fstream>
#include <sstream>

#include "absl/strings/str_cat.h"

namespace gvd {
namespace {

// Equal, in time that depends on the lengths only.
bool ConstantTimeEqual(const std::string& a, const std::string& b) {
  if (a.size() != b.size()) return false;
  unsigned char diff = 0;
  for (size_t i = 0; i < a.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
}

}  // namespace

absl::StatusOr<TokenAuth> TokenAuth::Load(const std::string& path) {
  std::ifstream in(path);
  if (!in) return absl::FailedPreconditionError(absl::StrCat("cannot read tokens file ", path));
  TokenAuth auth;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    std::istringstream words(line);
    std::string secret, role, extra;
    if (!(words >> secret) || secret[0] == '#') continue;
    if (!(words >> role) || (role != "read" && role != "write") || (words >> extra)) {
      return absl::InvalidArgumentError(
          absl::StrCat(path, ":", n, ": expected \"TOKEN read\" or \"TOKEN write\""));
    }
    if (secret.size() < 16) {
      return absl::InvalidArgumentError(
          absl::StrCat(path, ":", n, ": tokens must be at least 16 characters"));
    }
    auth.tokens_.push_back({secret, role == "write"});
  }
  if (auth.tokens_.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(path, " holds no token"));
  }
  return auth;
}

absl::Status TokenAuth::Check(const std::string& authorization, bool write) const {
  if (authorization.empty()) {
    return absl::UnauthenticatedError(
        "this server needs a bearer token (metadata \"authorization: Bearer TOKEN\")");
  }
  const std::string prefix = "Bearer ";
  if (authorization.compare(0, prefix.size(), prefix) != 0) {
    return absl::UnauthenticatedError("the authorization metadata must be \"Bearer TOKEN\"");
  }
  const std::string presented = authorization.substr(prefix.size());
  const Token* match = nullptr;
  for (const Token& t : tokens_) {
    if (ConstantTimeEqual(t.secret, presented)) match = &t;
  }
  if (match == nullptr) return absl::UnauthenticatedError("unknown bearer token");
  if (write && !match->can_write) {
    return absl::PermissionDeniedError("this token may read but not write");
  }
  return absl::OkStatus();
}

}  // namespace gvd

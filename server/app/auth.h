// Bearer-token authentication: tokens from a file, each allowed to read, or to read and write.
#pragma once

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace gvd {

// Immutable once loaded; thread-safe.
class TokenAuth {
 public:
  // Reads FILE: one "TOKEN read" or "TOKEN write" per line ("write" also reads); blank lines
  // and lines starting with '#' are skipped. Tokens are 16 or more printable characters.
  static absl::StatusOr<TokenAuth> Load(const std::string& path);

  // OK when a call's authorization (its "authorization" metadata, or HTTP header; empty when
  // it has none) is "Bearer TOKEN" for a known token that may do it; else UNAUTHENTICATED (no
  // or unknown token) or PERMISSION_DENIED (a read-only token asking to write). Tokens are
  // compared in constant time.
  absl::Status Check(const std::string& authorization, bool write) const;

  size_t size() const { return tokens_.size(); }

 private:
  struct Token {
    std::string secret;
    bool can_write;
  };
  std::vector<Token> tokens_;
};

}  // namespace gvd

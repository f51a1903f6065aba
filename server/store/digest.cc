#include "server/store/digest.h"

#include <openssl/evp.h>

#include "render/scene/codec.h"

namespace gvd {

uint64_t SiteDigest(std::string_view stored_bytes) {
  // Fetched once: a fetch by name on each call would cost more than the hash.
  static EVP_MD* const sha256 = EVP_MD_fetch(nullptr, "SHA256", nullptr);
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int size = 0;
  EVP_Digest(stored_bytes.data(), stored_bytes.size(), md, &size, sha256, nullptr);
  uint64_t digest = 0;
  for (int i = 0; i < 8; ++i) digest = digest << 8 | md[i];
  return digest;
}

uint64_t SiteDigest(const Site& site) { return SiteDigest(EncodeSite(site)); }
uint64_t SiteDigest(const Site3& site) { return SiteDigest(EncodeSite(site)); }

}  // namespace gvd

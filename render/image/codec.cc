#include "render/image/codec.h"

#include <dlfcn.h>
#include <unistd.h>

#include <climits>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"

namespace gvd {
namespace {

// The module, loaded once: beside the running program as installed (GVD_IMAGE_CODEC_INSTALLED,
// relative to its folder), else where the build made it (GVD_IMAGE_CODEC_BUILT).
absl::StatusOr<const ImageCodec*> Load() {
  std::vector<std::string> paths;
  char exe[PATH_MAX];
  if (const ssize_t n = readlink("/proc/self/exe", exe, sizeof(exe) - 1); n > 0) {
    const std::string self(exe, size_t(n));
    paths.push_back(absl::StrCat(self.substr(0, self.rfind('/') + 1), GVD_IMAGE_CODEC_INSTALLED));
  }
  paths.push_back(GVD_IMAGE_CODEC_BUILT);
  std::string errors;
  for (const std::string& path : paths) {
    if (void* module = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL)) {
      using Entry = const ImageCodec* (*)();
      if (auto entry = reinterpret_cast<Entry>(dlsym(module, "gvd_image_codec"))) return entry();
      absl::StrAppend(&errors, "; ", path, " has no gvd_image_codec");
      continue;
    }
    absl::StrAppend(&errors, "; ", dlerror());
  }
  return absl::InternalError(
      absl::StrCat("images need gvd's image module, which did not load", errors));
}

absl::StatusOr<const ImageCodec*> Codec() {
  static const absl::StatusOr<const ImageCodec*> codec = Load();
  return codec;
}

}  // namespace

absl::Status EncodeRaster(const std::string& name, const RasterView& raster,
                          std::vector<unsigned char>* bytes) {
  absl::StatusOr<const ImageCodec*> codec = Codec();
  if (!codec.ok()) return codec.status();
  return (*codec)->encode(name, raster, bytes);
}

absl::Status DecodeRaster(std::string_view bytes, const std::string& name,
                          const std::function<absl::Status(const RasterHeader&)>& header,
                          std::vector<float>* pixels) {
  absl::StatusOr<const ImageCodec*> codec = Codec();
  if (!codec.ok()) return codec.status();
  return (*codec)->decode(bytes, name, header, pixels);
}

}  // namespace gvd

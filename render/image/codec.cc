#include "render/image/codec.h"

#include <dlfcn.h>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "gvd_modules.h"

namespace gvd {
namespace {

// The module, loaded once.
absl::StatusOr<const ImageCodec*> Load() {
  std::string error;
  void* module = OpenModule("libgvd_image_codec.so", &error);
  auto entry = module ? reinterpret_cast<const ImageCodec* (*)()>(dlsym(module, "gvd_image_codec"))
                      : nullptr;
  if (module && !entry) error = dlerror();
  if (!entry) return absl::InternalError(absl::StrCat("images need gvd's image module: ", error));
  return entry();
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

// The field module (field_image.h): OpenImageIO's writers.
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "client/cli/field_image.h"

namespace {

// Writes rows of pixels given from the bottom row up (as the API sends them) top row first.
absl::Status WritePixels(const std::string& path, uint32_t w, uint32_t h, int channels,
                         OIIO::TypeDesc type, const void* bottom_up, size_t pixel_bytes) {
  auto out = OIIO::ImageOutput::create(path);
  if (!out) return absl::InvalidArgumentError(absl::StrCat("cannot write ", path, ": ", OIIO::geterror()));
  OIIO::ImageSpec spec(int(w), int(h), channels, type);
  const auto* base = static_cast<const char*>(bottom_up);
  // A negative y stride walks the rows from the last (the top) down.
  const OIIO::stride_t row = OIIO::stride_t(w * pixel_bytes);
  if (!out->open(path, spec) ||
      !out->write_image(type, base + size_t(h - 1) * w * pixel_bytes, OIIO::stride_t(pixel_bytes),
                        -row) ||
      !out->close()) {
    return absl::InternalError(absl::StrCat("writing ", path, ": ", out->geterror()));
  }
  return absl::OkStatus();
}

}  // namespace

extern "C" __attribute__((visibility("default"))) absl::Status gvd_write_field(
    const std::string& path, uint32_t w, uint32_t h, const float* v) {
  if (absl::EndsWith(path, ".exr") || absl::EndsWith(path, ".tif") || absl::EndsWith(path, ".tiff")) {
    return WritePixels(path, w, h, 1, OIIO::TypeDesc::FLOAT, v, sizeof(float));
  }
  float top = 0;
  for (size_t k = 0; k < size_t{w} * h; ++k) {
    if (std::isfinite(v[k])) top = std::max(top, v[k]);
  }
  std::vector<uint16_t> grey(size_t{w} * h);
  for (size_t k = 0; k < grey.size(); ++k) {
    grey[k] = std::isfinite(v[k]) && top > 0 ? uint16_t(std::lround(v[k] / top * 65535)) : 0;
  }
  return WritePixels(path, w, h, 1, OIIO::TypeDesc::UINT16, grey.data(), 2);
}

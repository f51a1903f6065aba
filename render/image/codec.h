// Images encoded and decoded through OpenImageIO, which lives in a module of its own
// (libgvd_image_codec.so, codec_oiio.cc) loaded on the first call: OpenImageIO brings some 260
// libraries, whose loading took two thirds of a server's start (on llvmpipe, 0.29 s to its
// port without them against 0.94 s with them), in every process, image or not.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "absl/status/status.h"

namespace gvd {

// Pixels to encode: `channels` values of `type` a pixel, pixels `pixel_bytes` apart, rows
// `row_bytes` apart from the top row at `top` down (0: packed; negative: rows kept bottom
// up). Types are OpenImageIO's names: "uint8", "uint16", "float".
struct RasterView {
  uint32_t width = 0, height = 0, channels = 0;
  std::string type;
  const void* top = nullptr;
  std::ptrdiff_t pixel_bytes = 0, row_bytes = 0;
  // The type written, where the format holds it; empty: `type`; one OpenImageIO does not know:
  // "uint8".
  std::string file_type;
  std::vector<std::string> channel_names;                         // empty: the format's own
  std::vector<std::pair<std::string, std::string>> text_attributes;  // ("compression", "zip")
  std::vector<std::pair<std::string, float>> float_attributes;
};

// An encoded image's header: its size, channels and pixel type (OpenImageIO's name).
struct RasterHeader {
  uint32_t width = 0, height = 0, channels = 0;
  std::string type;
};

// Encodes `raster` as the format whose files end as `name` does ("image.png"), into `bytes`.
// INVALID_ARGUMENT where no writer takes that name, INTERNAL where the writer fails; both
// with OpenImageIO's message.
absl::Status EncodeRaster(const std::string& name, const RasterView& raster,
                          std::vector<unsigned char>* bytes);
// Decodes `bytes` with the reader of `name`'s format only, as floats, rows top first.
// `header` sees the header before any pixel is decoded; its error is returned as it is.
// INVALID_ARGUMENT, with the reader's message, for bytes that reader does not decode.
absl::Status DecodeRaster(std::string_view bytes, const std::string& name,
                          const std::function<absl::Status(const RasterHeader&)>& header,
                          std::vector<float>* pixels);

// What the module gives: the two calls above, as it makes them.
struct ImageCodec {
  absl::Status (*encode)(const std::string& name, const RasterView& raster,
                         std::vector<unsigned char>* bytes);
  absl::Status (*decode)(std::string_view bytes, const std::string& name,
                         const std::function<absl::Status(const RasterHeader&)>& header,
                         std::vector<float>* pixels);
};

}  // namespace gvd

// The module's one entry point.
extern "C" const gvd::ImageCodec* gvd_image_codec();

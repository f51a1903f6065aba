// Voronoi mosaics of images (paper sec. 7.3): each tile a Voronoi region of a point site,
// coloured from the image. Images come and go as encoded bytes, through OpenImageIO; the
// diagram comes from the caller (the server renders the sites on a render thread).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "render/kernel/grid2.h"

namespace gvd {

// An image's pixels as floats, row-major from the top row, `channels` per pixel.
struct Image {
  uint32_t width = 0, height = 0, channels = 0;
  std::vector<float> pixels;
  std::string pixel_type;   // the file's (OpenImageIO's name: "uint8", "uint16"), to write alike
  std::string file_format;  // OpenImageIO's name of the file's format: "png", "jpeg", ...

  float at(uint32_t x, uint32_t row, uint32_t c) const {
    return pixels[(size_t{row} * width + x) * channels + c];
  }
};

// Decodes an image file held in `bytes`: PNG, JPEG, WebP, GIF, BMP or PNM, told by its first
// bytes (no other format's decoder sees them). `admit` is called with the header (pixels
// still empty) before any pixel is decoded, so that a caller refuses an image too large for
// it before it takes the memory; its error is returned. INVALID_ARGUMENT, naming `field`, for
// another format, a damaged file, a side of 0 or more than 4 channels.
absl::StatusOr<Image> ReadImage(std::string_view bytes, const std::string& field,
                                const std::function<absl::Status(const Image&)>& admit);
// Encodes `image` in `file_format` ("png", "jpeg" at quality 90, "webp" or "pnm") in its own
// pixel type where the format holds it. JPEG and PNM hold no alpha: an image with one is
// written without it.
absl::StatusOr<std::string> WriteImage(const Image& image, const std::string& file_format);
// The MIME type of a format WriteImage writes.
std::string MimeType(const std::string& file_format);

struct MosaicOptions {
  uint32_t tiles = 1000;
  // Sites drawn with density proportional to the image's gradient (plus a tenth of its mean,
  // so that flat areas keep some tiles): more, smaller tiles where there is detail.
  bool adaptive = false;
  uint64_t seed = 0;
  // Colour each tile with the mean of its pixels instead of the pixel at its site.
  bool mean = false;
};

// The grid of an image: its pixels, over [0, width] x [0, height] with y up (the image's top
// row is the grid's last).
Grid ImageGrid(const Image& image);

// The sites of a mosaic of `image` in the plane of its grid, one point per tile.
std::vector<Vec2> MosaicSites(const Image& image, const MosaicOptions& options);

// The bytes a mosaic of a width x height image of `channels` takes while it is made: the
// image and the mosaic as floats, the diagram's ids and its frame, the render target.
uint64_t MosaicBytes(uint32_t width, uint32_t height, uint32_t channels);

// The mosaic of `image` on `ids`, the diagram of `sites` on ImageGrid(image) (per pixel,
// row-major from row 0 at the bottom: 1 + the index of its nearest site, or 0): each pixel
// the colour of its tile.
absl::StatusOr<Image> MakeMosaic(const Image& image, const std::vector<Vec2>& sites,
                                 const std::vector<uint32_t>& ids, const MosaicOptions& options);

}  // namespace gvd

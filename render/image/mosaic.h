// Voronoi mosaics of images (paper sec. 7.3): each tile a Voronoi region of a point site,
// coloured from the image. Images go in and out through OpenImageIO.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "render/kernel/grid2.h"

namespace gvd {

// An image's pixels as floats, row-major from the top row, `channels` per pixel.
struct Image {
  uint32_t width = 0, height = 0, channels = 0;
  std::vector<float> pixels;
  std::string format;  // the file's pixel type (OpenImageIO's name), to write back alike

  float at(uint32_t x, uint32_t row, uint32_t c) const {
    return pixels[(size_t{row} * width + x) * channels + c];
  }
};

absl::StatusOr<Image> ReadImage(const std::string& path);
absl::Status WriteImage(const std::string& path, const Image& image);

struct MosaicOptions {
  uint32_t tiles = 1000;
  // Sites drawn with density proportional to the image's gradient (plus a tenth of its mean,
  // so that flat areas keep some tiles): more, smaller tiles where there is detail.
  bool adaptive = false;
  uint64_t seed = 1;
  // Colour each tile with the mean of its pixels instead of the pixel at its site.
  bool mean = false;
};

// The sites of a mosaic of `image`: in the plane of its grid, [0, width] x [0, height] with y
// up (the image's top row is the grid's last), one point per tile.
std::vector<Vec2> MosaicSites(const Image& image, const MosaicOptions& options);

// Computes the discrete Voronoi diagram of `sites` on `grid`: per pixel, 1 + the index of
// its nearest site (row-major from row 0, the bottom), or 0.
using DiagramFn = std::function<absl::StatusOr<std::vector<uint32_t>>(
    const Grid& grid, const std::vector<Vec2>& sites)>;

// The mosaic of `image` on the diagram of `sites`: each pixel the colour of its tile.
absl::StatusOr<Image> MakeMosaic(const Image& image, const std::vector<Vec2>& sites,
                                 const std::vector<uint32_t>& ids, const MosaicOptions& options);

// The grid of an image: its pixels, over [0, width] x [0, height].
Grid ImageGrid(const Image& image);

// The options from command flags, by name (--tiles N, --seed S, and the switches --adaptive
// and --mean, present with any value); INVALID_ARGUMENT naming a bad value.
absl::StatusOr<MosaicOptions> MosaicOptionsFromFlags(
    const std::map<std::string, std::string>& flags);

// The whole mosaic command: reads `in`, places the sites, takes their diagram from `diagram`,
// colours the tiles and writes `out`. Returns the line to print: the sizes, the diagram's
// `source` and the times taken.
absl::StatusOr<std::string> RunMosaic(const std::string& in, const std::string& out,
                                      const MosaicOptions& options, const DiagramFn& diagram,
                                      const std::string& source);

}  // namespace gvd

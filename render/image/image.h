// A frame's layers as encoded images (PNG, EXR) through OpenImageIO.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "render/scene/frame.h"
#include "render/scene/volume.h"

namespace gvd {

// kSiteIndex: 1 + an index into EncodedImage::site_ids per pixel, in 24-bit RGB (0: none).
enum class ImageLayer { kIds, kFeatures, kDistance, kSiteIndex };
enum class ImageFormat { kPng, kExr };

struct ImageOptions {
  ImageLayer layer = ImageLayer::kIds;
  ImageFormat format = ImageFormat::kPng;
  PixelRect rect;           // the pixels to show; CONTRACT: not empty, inside the grid
  bool draw_sites = false;  // the sites' geometry in white on top (PNG)
  std::vector<Vec2> polyline;  // drawn in red on top (PNG): a planned path, say
  uint32_t slice = 0;          // a volume's: the slice shown (rect is of its voxels)
};

struct EncodedImage {
  std::vector<unsigned char> bytes;
  std::string mime_type;
  uint32_t width = 0, height = 0;
  std::vector<std::string> site_ids;  // kSiteIndex: the sites the pixels name, in order
};

// The colour of a site (or of one of its features): stable, from a hash of its id, bright
// enough to stand apart from the black of empty pixels.
void SiteColour(const std::string& id, uint32_t feature, uint8_t rgb[3]);

// Encodes a layer of the frame: row 0 of the image is the top of the window (max y).
// Pixels held by a site that is no candidate there (within DrawMargin of its max_distance
// or side) show the site that is best at their centre (exactly in a NEAREST diagram, within
// the frame's bound in a FARTHEST one), or empty. CONTRACT: the frame is not empty.
absl::StatusOr<EncodedImage> EncodeImage(const Frame& frame, const ImageOptions& options);
// The same of a slice of a volume (options.slice, rect of its voxels; no draw_sites or
// polyline): its voxels' sites, the features of those sites nearest to the voxels' centres,
// or their values. CONTRACT: the slice exists.
absl::StatusOr<EncodedImage> EncodeImage(const Volume& volume, const ImageOptions& options);

}  // namespace gvd

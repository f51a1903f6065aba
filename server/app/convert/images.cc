#include "server/app/convert/images.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "server/app/convert/common.h"
#include "server/log.h"

namespace gvd {

absl::Status ToImageOptions(const v1::RenderImageRequest& request, const Grid& grid,
                            ImageOptions* options) {
  switch (request.layer()) {
    case v1::RenderImageRequest::LAYER_UNSPECIFIED:
    case v1::RenderImageRequest::LAYER_IDS:
      options->layer = ImageLayer::kIds;
      break;
    case v1::RenderImageRequest::LAYER_FEATURES:
      options->layer = ImageLayer::kFeatures;
      break;
    case v1::RenderImageRequest::LAYER_DISTANCE:
      options->layer = ImageLayer::kDistance;
      break;
    case v1::RenderImageRequest::LAYER_SITE_INDEX:
      options->layer = ImageLayer::kSiteIndex;
      break;
    default:
      return Invalid(absl::StrCat("layer is ", request.layer(),
                                  "; it must be LAYER_IDS, LAYER_FEATURES, LAYER_DISTANCE or LAYER_SITE_INDEX"));
  }
  switch (request.format()) {
    case v1::RenderImageRequest::FORMAT_UNSPECIFIED:
    case v1::RenderImageRequest::FORMAT_PNG:
      options->format = ImageFormat::kPng;
      break;
    case v1::RenderImageRequest::FORMAT_EXR:
      options->format = ImageFormat::kExr;
      break;
    default:
      return Invalid(absl::StrCat("format is ", request.format(), "; it must be FORMAT_PNG or FORMAT_EXR"));
  }
  const bool exr = options->format == ImageFormat::kExr;
  if (exr && options->layer != ImageLayer::kDistance) {
    return Invalid("format FORMAT_EXR holds the LAYER_DISTANCE layer only");
  }
  if (exr && request.draw_sites()) return Invalid("draw_sites needs format FORMAT_PNG");
  if (options->layer == ImageLayer::kSiteIndex &&
      (request.draw_sites() || request.polyline_size() > 0)) {
    return Invalid(
        "layer LAYER_SITE_INDEX takes neither draw_sites nor polyline: its pixels are numbers");
  }
  if (request.has_z() || request.has_slice()) {
    return Invalid("z and slice are for 3D scenes; this scene is 2D");
  }
  options->draw_sites = request.draw_sites();
  options->rect = grid.all();
  if (request.has_window()) {
    if (auto s = ToPixelRect(request.window(), grid, &options->rect); !s.ok()) return s;
  }
  for (int k = 0; k < request.polyline_size(); ++k) {
    Vec2 p;
    if (auto s = ToPoint(request.polyline(k), FieldPath("polyline")[k], &p); !s.ok()) return s;
    options->polyline.push_back(p);
  }
  if (!options->polyline.empty() && exr) return Invalid("polyline needs format FORMAT_PNG");
  return absl::OkStatus();
}

absl::Status ToImageOptions(const v1::RenderImageRequest& request, const Grid3& grid,
                            ImageOptions* options) {
  if (request.draw_sites() || request.polyline_size() > 0) {
    return Invalid("draw_sites and polyline are for 2D scenes");
  }
  if (request.width_px() != 0 || request.height_px() != 0) {
    return Invalid(
        "width_px and height_px are for 2D scenes: a 3D scene's image is a slice "
        "of its voxels");
  }
  if (request.has_z() == request.has_slice()) {
    return Invalid("a 3D scene's image is of one slice: set z or slice (one of them)");
  }
  uint32_t k = 0;
  if (request.has_slice()) {
    if (request.slice() >= grid.depth) {
      return Invalid(absl::StrCat("slice is ", request.slice(), "; the scene has ", grid.depth,
                                  " (0 to ", grid.depth - 1, ")"));
    }
    k = request.slice();
  } else {
    const double z = request.z();
    if (!(z >= grid.box.min_z && z <= grid.box.max_z)) {
      return Invalid(absl::StrCat("z is ", FormatNumber(z), "; it must lie in the box's [",
                                  FormatNumber(grid.box.min_z), ", ", FormatNumber(grid.box.max_z),
                                  "]"));
    }
    k = static_cast<uint32_t>(
        std::min<double>(grid.depth - 1, std::floor(grid.ToVoxel({0, 0, z}).z)));
  }
  v1::RenderImageRequest plane = request;
  plane.clear_z();
  plane.clear_slice();
  Grid g;
  g.window = {grid.box.min_x, grid.box.min_y, grid.box.max_x, grid.box.max_y};
  g.width = grid.width;
  g.height = grid.height;
  if (auto s = ToImageOptions(plane, g, options); !s.ok()) return s;
  options->slice = k;
  return absl::OkStatus();
}

absl::Status ToMosaicOptions(const v1::RenderMosaicRequest& request, const ServerLimits& limits,
                             MosaicOptions* options, std::string* format) {
  options->tiles = request.tiles() == 0 ? 1000 : request.tiles();
  if (options->tiles > limits.max_sites_per_scene) {
    return Invalid(absl::StrCat("tiles is ", options->tiles, "; it must be 1 to ",
                                limits.max_sites_per_scene, " (--max-sites-per-scene)"));
  }
  options->adaptive = request.adaptive();
  options->seed = request.seed();
  options->mean = request.mean();
  switch (request.format()) {
    case v1::RenderMosaicRequest::FORMAT_UNSPECIFIED:
      *format = "";
      break;
    case v1::RenderMosaicRequest::FORMAT_PNG:
      *format = "png";
      break;
    case v1::RenderMosaicRequest::FORMAT_JPEG:
      *format = "jpeg";
      break;
    case v1::RenderMosaicRequest::FORMAT_WEBP:
      *format = "webp";
      break;
    case v1::RenderMosaicRequest::FORMAT_PNM:
      *format = "pnm";
      break;
    default:
      return Invalid(absl::StrCat(
          "format is ", request.format(),
          "; it must be FORMAT_UNSPECIFIED, FORMAT_PNG, FORMAT_JPEG, FORMAT_WEBP or FORMAT_PNM"));
  }
  return absl::OkStatus();
}

absl::Status MosaicImageFits(const Image& header, const ServerLimits& limits) {
  if (header.width > limits.max_side_px || header.height > limits.max_side_px) {
    return Invalid(absl::StrCat("image is ", header.width, "x", header.height,
                                " pixels; a side may be 1 to ", limits.max_side_px,
                                " (--max-side-px)"));
  }
  if (uint64_t{header.width} * header.height > limits.max_scene_pixels) {
    return absl::ResourceExhaustedError(absl::StrCat("image is ", header.width, "x",
                                                     header.height, " pixels; the limit is ",
                                                     limits.max_scene_pixels));
  }
  return absl::OkStatus();
}

}  // namespace gvd

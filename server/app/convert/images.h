// Images: RenderImageRequest's layer, format, drawing options, window and polyline, checked
// together, for a 2D scene's frame or a 3D scene's slice; RenderMosaicRequest's options and
// the image it brings.
#pragma once

#include "absl/status/status.h"
#include "gvd/v1/voronoi.pb.h"
#include "render/image/image.h"
#include "render/image/mosaic.h"
#include "render/kernel/grid2.h"
#include "render/kernel/grid3.h"
#include "server/app/limits.h"

namespace gvd {

// The options of an image of a 2D scene's frame on `grid`.
absl::Status ToImageOptions(const v1::RenderImageRequest& request, const Grid& grid,
                            ImageOptions* options);
// The options of an image of one slice of a 3D scene (z or slice), its rect of the slice's
// voxels.
absl::Status ToImageOptions(const v1::RenderImageRequest& request, const Grid3& grid,
                            ImageOptions* options);

// A mosaic's options and format (OpenImageIO's name; empty: the image's own, PNG for a GIF
// or a BMP). The image itself is checked as it is decoded (MosaicImageFits).
absl::Status ToMosaicOptions(const v1::RenderMosaicRequest& request, const ServerLimits& limits,
                             MosaicOptions* options, std::string* format);
// Whether a mosaic's image (its header: size and channels) fits --max-side-px.
absl::Status MosaicImageFits(const Image& header, const ServerLimits& limits);

}  // namespace gvd

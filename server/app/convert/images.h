// Images: RenderImageRequest's layer, format, drawing options, window and polyline, checked
// together, for a 2D scene's frame or a 3D scene's slice.
#pragma once

#include "absl/status/status.h"
#include "gvd/v1/voronoi.pb.h"
#include "render/image/image.h"
#include "render/kernel/grid2.h"
#include "render/kernel/grid3.h"

namespace gvd {

// The options of an image of a 2D scene's frame on `grid`.
absl::Status ToImageOptions(const v1::RenderImageRequest& request, const Grid& grid,
                            ImageOptions* options);
// The options of an image of one slice of a 3D scene (z or slice), its rect of the slice's
// voxels.
absl::Status ToImageOptions(const v1::RenderImageRequest& request, const Grid3& grid,
                            ImageOptions* options);

}  // namespace gvd

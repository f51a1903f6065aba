// The CLI's fields (distances, clearance) written as image files through OpenImageIO, which
// lives in a module of its own (libgvd_field_image.so, field_image_oiio.cc) loaded at the first
// field written: OpenImageIO's some 260 libraries took three quarters of every command's start
// (`gvd --help`: 0.10 s without them, 0.47 s with them).
#pragma once

#include <cstdint>
#include <string>

#include "absl/status/status.h"

namespace gvd::cli {

// Writes a w x h float field, given from the bottom row up (as the API sends it), to `path`
// in the format its extension names, top row first: 32-bit floats in EXR and TIFF, else 16
// bits scaled from 0 to its largest finite value (+infinity as 0). INVALID_ARGUMENT where no
// format takes the name, INTERNAL where writing fails; both naming the path.
absl::Status WriteField(const std::string& path, uint32_t w, uint32_t h, const float* v);

}  // namespace gvd::cli

// The module's one entry point: WriteField as it makes it.
extern "C" absl::Status gvd_write_field(const std::string& path, uint32_t w, uint32_t h,
                                        const float* v);

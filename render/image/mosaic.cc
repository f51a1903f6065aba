#include "render/image/mosaic.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <random>

#include "absl/strings/ascii.h"
#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "render/image/codec.h"

namespace gvd {

namespace {

// The formats ReadImage decodes, told by their first bytes: OpenImageIO's name, and the file
// extension its plugin answers to.
struct Sniffed {
  const char* format;
  const char* extension;
};

std::optional<Sniffed> Sniff(std::string_view b) {
  auto starts = [&](std::string_view magic) { return b.substr(0, magic.size()) == magic; };
  if (starts("\x89PNG\r\n\x1a\n")) return Sniffed{"png", "png"};
  if (starts("\xff\xd8\xff")) return Sniffed{"jpeg", "jpg"};
  if (starts("RIFF") && b.size() >= 12 && b.substr(8, 4) == "WEBP") return Sniffed{"webp", "webp"};
  if (starts("GIF87a") || starts("GIF89a")) return Sniffed{"gif", "gif"};
  if (starts("BM")) return Sniffed{"bmp", "bmp"};
  if (b.size() >= 3 && b[0] == 'P' && b[1] >= '1' && b[1] <= '6' &&
      absl::ascii_isspace(static_cast<unsigned char>(b[2]))) {
    return Sniffed{"pnm", "pnm"};
  }
  return std::nullopt;
}

}  // namespace

absl::StatusOr<Image> ReadImage(std::string_view bytes, const std::string& field,
                                const std::function<absl::Status(const Image&)>& admit) {
  const std::optional<Sniffed> sniffed = Sniff(bytes);
  if (!sniffed) {
    return absl::InvalidArgumentError(absl::StrCat(
        field, " is not a PNG, JPEG, WebP, GIF, BMP or PNM file (", bytes.size(),
        " bytes, starting \"", absl::CHexEscape(absl::string_view(bytes.data(), std::min<size_t>(8, bytes.size()))), "\")"));
  }
  const std::string name = absl::StrCat("image.", sniffed->extension);
  Image image;
  image.file_format = sniffed->format;
  bool admitted = true;  // no error of the header's checks or of `admit`
  const absl::Status s = DecodeRaster(bytes, name, [&](const RasterHeader& h) -> absl::Status {
    image.width = h.width;
    image.height = h.height;
    image.channels = h.channels;
    image.pixel_type = h.type;
    admitted = false;
    if (image.width == 0 || image.height == 0 || image.channels == 0 || image.channels > 4) {
      return absl::InvalidArgumentError(absl::StrCat(field, " is ", image.width, "x", image.height,
                                                     " pixels of ", image.channels,
                                                     " channels; a mosaic needs a pixel and 1 to 4 channels"));
    }
    if (auto s = admit(image); !s.ok()) return s;
    admitted = true;
    return absl::OkStatus();
  }, &image.pixels);
  if (s.ok()) return image;
  // The module's INVALID_ARGUMENT is the reader's message on bytes it cannot decode.
  if (!admitted || s.code() != absl::StatusCode::kInvalidArgument) return s;
  return absl::InvalidArgumentError(
      absl::StrCat(field, " is a damaged ", sniffed->format, " file: ", s.message()));
}

absl::StatusOr<std::string> WriteImage(const Image& image, const std::string& file_format) {
  const char* extension = file_format == "png"    ? "png"
                          : file_format == "jpeg" ? "jpg"
                          : file_format == "webp" ? "webp"
                          : file_format == "pnm"  ? "pnm"
                                                  : nullptr;
  if (extension == nullptr) {
    return absl::InvalidArgumentError(absl::StrCat("cannot write ", file_format, " images"));
  }
  // JPEG and PNM hold 1 or 3 channels: alpha (the second of two, the fourth of four) is left.
  uint32_t channels = image.channels;
  if ((file_format == "jpeg" || file_format == "pnm") && channels % 2 == 0) --channels;
  const auto pixel_bytes = std::ptrdiff_t(image.channels * sizeof(float));
  const RasterView raster{
      .width = image.width, .height = image.height, .channels = channels, .type = "float",
      .top = image.pixels.data(), .pixel_bytes = pixel_bytes,
      .file_type = file_format == "jpeg" || image.pixel_type.empty() ? "uint8" : image.pixel_type,
      // JPEG's quality; other formats ignore it.
      .text_attributes = {{"Compression", "jpeg:90"}}};
  std::vector<unsigned char> bytes;
  if (auto s = EncodeRaster(absl::StrCat("image.", extension), raster, &bytes); !s.ok()) return s;
  return std::string(bytes.begin(), bytes.end());
}

std::string MimeType(const std::string& file_format) {
  if (file_format == "pnm") return "image/x-portable-anymap";
  return absl::StrCat("image/", file_format);
}

uint64_t MosaicBytes(uint32_t width, uint32_t height, uint32_t channels) {
  // Floats for the image and the mosaic; per pixel an id, a frame's id and distance, and the
  // render target's id, depth and depth buffer.
  return uint64_t{width} * height * (2 * 4 * uint64_t{channels} + 4 + 8 + 12);
}

Grid ImageGrid(const Image& image) {
  return Grid{{0, 0, double(image.width), double(image.height)}, image.width, image.height};
}

std::vector<Vec2> MosaicSites(const Image& image, const MosaicOptions& options) {
  std::mt19937_64 rng(options.seed);
  std::uniform_real_distribution<double> unit(0, 1);
  const uint32_t w = image.width, h = image.height;
  std::vector<Vec2> sites;
  sites.reserve(options.tiles);
  if (!options.adaptive) {
    for (uint32_t k = 0; k < options.tiles; ++k) sites.push_back({unit(rng) * w, unit(rng) * h});
    return sites;
  }
  // Luminance, its Sobel gradient, and a cumulative weight per pixel.
  std::vector<float> lum(size_t{w} * h);
  for (uint32_t row = 0; row < h; ++row) {
    for (uint32_t x = 0; x < w; ++x) {
      float l = image.at(x, row, 0);
      if (image.channels >= 3) {
        l = 0.299f * image.at(x, row, 0) + 0.587f * image.at(x, row, 1) + 0.114f * image.at(x, row, 2);
      }
      lum[size_t{row} * w + x] = l;
    }
  }
  auto L = [&](int x, int row) {
    x = std::clamp(x, 0, int(w) - 1);
    row = std::clamp(row, 0, int(h) - 1);
    return lum[size_t(row) * w + x];
  };
  std::vector<double> weight(size_t{w} * h);
  double total = 0;
  for (int row = 0; row < int(h); ++row) {
    for (int x = 0; x < int(w); ++x) {
      double gx = L(x + 1, row - 1) + 2 * L(x + 1, row) + L(x + 1, row + 1) - L(x - 1, row - 1) -
                  2 * L(x - 1, row) - L(x - 1, row + 1);
      double gy = L(x - 1, row + 1) + 2 * L(x, row + 1) + L(x + 1, row + 1) - L(x - 1, row - 1) -
                  2 * L(x, row - 1) - L(x + 1, row - 1);
      double g = std::sqrt(gx * gx + gy * gy);
      weight[size_t(row) * w + x] = g;
      total += g;
    }
  }
  const double floor = total > 0 ? 0.1 * total / weight.size() : 1;
  double running = 0;
  for (double& v : weight) running = v = running + v + floor;
  for (uint32_t k = 0; k < options.tiles; ++k) {
    double u = unit(rng) * running;
    size_t at = std::upper_bound(weight.begin(), weight.end(), u) - weight.begin();
    at = std::min(at, weight.size() - 1);
    uint32_t x = static_cast<uint32_t>(at % w), row = static_cast<uint32_t>(at / w);
    // The grid's y is up: the image's row `row` is the grid's row h - 1 - row.
    sites.push_back({x + unit(rng), (h - 1 - row) + unit(rng)});
  }
  return sites;
}

absl::StatusOr<Image> MakeMosaic(const Image& image, const std::vector<Vec2>& sites,
                                 const std::vector<uint32_t>& ids, const MosaicOptions& options) {
  const uint32_t w = image.width, h = image.height, c = image.channels;
  if (ids.size() != size_t{w} * h) return absl::InternalError("the diagram does not match the image");
  std::vector<double> colour(sites.size() * c, 0);
  if (options.mean) {
    std::vector<double> count(sites.size(), 0);
    for (uint32_t j = 0; j < h; ++j) {
      for (uint32_t x = 0; x < w; ++x) {
        uint32_t id = ids[size_t{j} * w + x];
        if (id == 0) continue;
        count[id - 1] += 1;
        for (uint32_t k = 0; k < c; ++k) colour[(id - 1) * c + k] += image.at(x, h - 1 - j, k);
      }
    }
    for (size_t s = 0; s < sites.size(); ++s) {
      for (uint32_t k = 0; k < c; ++k) colour[s * c + k] /= std::max(1.0, count[s]);
    }
  } else {
    for (size_t s = 0; s < sites.size(); ++s) {
      uint32_t x = std::min(w - 1, static_cast<uint32_t>(sites[s].x));
      uint32_t j = std::min(h - 1, static_cast<uint32_t>(sites[s].y));
      for (uint32_t k = 0; k < c; ++k) colour[s * c + k] = image.at(x, h - 1 - j, k);
    }
  }
  Image out = image;
  for (uint32_t j = 0; j < h; ++j) {
    for (uint32_t x = 0; x < w; ++x) {
      uint32_t id = ids[size_t{j} * w + x];
      for (uint32_t k = 0; k < c; ++k) {
        out.pixels[(size_t{h - 1 - j} * w + x) * c + k] =
            id == 0 ? 0.0f : static_cast<float>(colour[(id - 1) * c + k]);
      }
    }
  }
  return out;
}

}  // namespace gvd

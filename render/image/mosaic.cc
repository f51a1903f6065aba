#include "render/image/mosaic.h"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace gvd {

absl::StatusOr<Image> ReadImage(const std::string& path) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) {
    return absl::NotFoundError(absl::StrCat("cannot read ", path, ": ", OIIO::geterror()));
  }
  const OIIO::ImageSpec& spec = in->spec();
  Image image;
  image.width = static_cast<uint32_t>(spec.width);
  image.height = static_cast<uint32_t>(spec.height);
  image.channels = static_cast<uint32_t>(spec.nchannels);
  image.format = spec.format.c_str();
  image.pixels.resize(size_t{image.width} * image.height * image.channels);
  if (image.pixels.empty() ||
      !in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, image.pixels.data())) {
    return absl::InvalidArgumentError(absl::StrCat("cannot read the pixels of ", path, ": ",
                                                   in->geterror()));
  }
  return image;
}

absl::Status WriteImage(const std::string& path, const Image& image) {
  auto out = OIIO::ImageOutput::create(path);
  if (!out) {
    return absl::InvalidArgumentError(
        absl::StrCat("cannot write ", path, ": ", OIIO::geterror()));
  }
  OIIO::TypeDesc format(image.format.empty() ? "uint8" : image.format.c_str());
  if (format == OIIO::TypeDesc::UNKNOWN) format = OIIO::TypeDesc::UINT8;
  OIIO::ImageSpec spec(int(image.width), int(image.height), int(image.channels), format);
  spec.attribute("Compression", "jpeg:90");  // for JPEG; other formats ignore it
  if (!out->open(path, spec) ||
      !out->write_image(OIIO::TypeDesc::FLOAT, image.pixels.data()) || !out->close()) {
    return absl::InternalError(absl::StrCat("writing ", path, ": ", out->geterror()));
  }
  return absl::OkStatus();
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

absl::StatusOr<MosaicOptions> MosaicOptionsFromFlags(
    const std::map<std::string, std::string>& flags) {
  MosaicOptions options;
  if (auto t = flags.find("--tiles"); t != flags.end()) {
    if (!absl::SimpleAtoi(t->second, &options.tiles) || options.tiles == 0) {
      return absl::InvalidArgumentError(
          absl::StrCat("--tiles needs a positive count, not \"", t->second, "\""));
    }
  }
  if (auto s = flags.find("--seed"); s != flags.end()) {
    if (!absl::SimpleAtoi(s->second, &options.seed)) {
      return absl::InvalidArgumentError(
          absl::StrCat("--seed needs a number, not \"", s->second, "\""));
    }
  }
  options.adaptive = flags.count("--adaptive") > 0;
  options.mean = flags.count("--mean") > 0;
  return options;
}

absl::StatusOr<std::string> RunMosaic(const std::string& in, const std::string& out,
                                      const MosaicOptions& options, const DiagramFn& diagram,
                                      const std::string& source) {
  using Clock = std::chrono::steady_clock;
  auto seconds = [](Clock::time_point since) {
    return std::chrono::duration<double>(Clock::now() - since).count();
  };
  const auto start = Clock::now();
  auto image = ReadImage(in);
  if (!image.ok()) return image.status();
  std::vector<Vec2> sites = MosaicSites(*image, options);
  const auto diagram_start = Clock::now();
  auto ids = diagram(ImageGrid(*image), sites);
  if (!ids.ok()) return ids.status();
  const double diagram_s = seconds(diagram_start);
  auto mosaic = MakeMosaic(*image, sites, *ids, options);
  if (!mosaic.ok()) return mosaic.status();
  if (auto s = WriteImage(out, *mosaic); !s.ok()) return s;
  return absl::StrFormat("wrote %s: %ux%u, %u%s tiles, %s; diagram %s in %.3g s, %.3g s in all",
                         out, image->width, image->height, sites.size(),
                         options.adaptive ? " adaptive" : " random",
                         options.mean ? "tile means" : "colours at the sites", source, diagram_s,
                         seconds(start));
}

}  // namespace gvd

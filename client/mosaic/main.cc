// gvd-mosaic: a Voronoi mosaic of an image, rendered in this process on its own EGL context
// (a GPU, else Mesa's llvmpipe), with no server. `gvd mosaic` makes the same mosaic with the
// diagram from a server.
#include <cstdio>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/strings/str_cat.h"
#include "render/gl/context.h"
#include "render/gl/rasterizer.h"
#include "render/gl/scene_raster.h"
#include "render/image/mosaic.h"
#include "server/flags.h"

// The flags, read by gvd::flags; the mosaic's own are checked by MosaicOptionsFromFlags.
ABSL_FLAG(std::string, tiles, "", "<N> tiles at random (default 1000)");
ABSL_FLAG(bool, adaptive, false, "more and smaller tiles where the image has detail");
ABSL_FLAG(std::string, seed, "", "<S> the random sites' seed");
ABSL_FLAG(bool, mean, false, "each tile the mean colour of its pixels");
ABSL_FLAG(std::string, egl_device, "", "<auto|hardware|software> which EGL device renders");

namespace gvd {
namespace {

constexpr const char* kUsage =
    R"(usage: gvd-mosaic IN OUT [--tiles N] [--adaptive] [--seed S] [--mean] [--egl-device D]
  IN (any format OpenImageIO reads) as a Voronoi mosaic in OUT: N tiles (default 1000) at
  random, or --adaptive: more and smaller where the image has detail; each tile the colour
  at its site, or --mean of the tile. The diagram is rendered exactly here, on EGL:
  --egl-device auto (a GPU, else llvmpipe; the default), hardware or software.
)";

[[noreturn]] void Usage(const std::string& message) {
  std::cerr << "gvd-mosaic: " << message << "\n" << kUsage;
  std::exit(2);
}

// The diagram of `sites` on `grid`, drawn exactly on this process's EGL context.
absl::StatusOr<std::vector<uint32_t>> EmbeddedDiagram(DevicePreference device, const Grid& grid,
                                                      const std::vector<Vec2>& sites) {
  auto context = GlContext::Create(device);
  if (!context.ok()) return context.status();
  auto rasterizer = Rasterizer::Create((*context)->info());
  if (!rasterizer.ok()) return rasterizer.status();
  SiteTable table;
  table.reserve(sites.size());
  for (size_t s = 0; s < sites.size(); ++s) {
    table.push_back({absl::StrCat("t", s), PointSite{sites[s]}});
  }
  auto frame =
      RenderOnce(**rasterizer, grid, grid.pixel_size(), 1, table, nullptr, RenderMode::kExact);
  if (!frame.ok()) return frame.status();
  std::vector<uint32_t> ids(grid.pixel_count());
  for (uint32_t j = 0; j < grid.height; ++j) {
    for (uint32_t i = 0; i < grid.width; ++i) {
      ids[size_t{j} * grid.width + i] = (*frame)->id_at(i, j);
    }
  }
  return ids;
}

int Main(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (flags::WantsHelp(args)) {
    std::fputs(kUsage, stdout);
    return 0;
  }
  auto parsed = flags::Parse(args, /*words=*/true);
  if (!parsed.ok()) Usage(std::string(parsed.status().message()));
  const std::vector<std::string>& words = parsed->words;
  std::map<std::string, std::string> flags;  // as MosaicOptionsFromFlags reads them
  for (const auto& [name, value] : parsed->given) flags["--" + name] = value;
  if (words.size() != 2) Usage("IN and OUT are needed");
  auto options = MosaicOptionsFromFlags(flags);
  if (!options.ok()) Usage(std::string(options.status().message()));
  DevicePreference device = DevicePreference::kAuto;
  if (auto d = flags.find("--egl-device"); d != flags.end()) {
    auto parsed = ParseDevicePreference(d->second);
    if (!parsed.ok()) Usage(std::string(parsed.status().message()));
    device = *parsed;
  }
  auto report = RunMosaic(
      words[0], words[1], *options,
      [&](const Grid& grid, const std::vector<Vec2>& sites) {
        return EmbeddedDiagram(device, grid, sites);
      },
      "embedded");
  if (!report.ok()) {
    std::cerr << "gvd-mosaic: " << report.status().message() << "\n";
    return 1;
  }
  std::cout << *report << "\n";
  return 0;
}

}  // namespace
}  // namespace gvd

int main(int argc, char** argv) { return gvd::Main(argc, argv); }

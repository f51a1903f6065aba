// gvd-mosaic: a Voronoi mosaic of an image, rendered in this process on its own EGL context
// (a GPU, else Mesa's llvmpipe), with no server. `gvd mosaic` makes the same mosaic with the
// diagram from a server.
#include <cstdio>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "render/gl/context.h"
#include "render/gl/rasterizer.h"
#include "render/gl/scene_raster.h"
#include "render/image/mosaic.h"

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
  std::vector<std::string> words;
  std::map<std::string, std::string> flags;
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    }
    if (arg.rfind("--", 0) != 0) {
      words.push_back(arg);
    } else if (arg == "--adaptive" || arg == "--mean") {
      flags[arg] = "1";
    } else if (arg == "--tiles" || arg == "--seed" || arg == "--egl-device") {
      if (i + 1 == argc) Usage(arg + " needs a value");
      flags[arg] = argv[++i];
    } else {
      Usage("unknown flag " + arg);
    }
  }
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

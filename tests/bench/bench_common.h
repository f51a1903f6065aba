// What the benchmark programs share: one GL context for the run, random sites.
#pragma once

#include <cstdlib>
#include <memory>
#include <random>
#include <string>

#include "render/gl/context.h"
#include "render/gl/rasterizer.h"
#include "render/kernel/site2.h"

namespace gvd {

inline SiteTable RandomSites(size_t n, const Window& w, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> ux(w.min_x, w.max_x), uy(w.min_y, w.max_y);
  SiteTable sites;
  sites.reserve(n);
  for (size_t i = 0; i < n; ++i) sites.push_back({std::to_string(i), PointSite{{ux(rng), uy(rng)}}});
  return sites;
}

// One GL context for the whole run, current on the main thread.
struct Gl {
  std::unique_ptr<GlContext> context;
  std::unique_ptr<Rasterizer> rasterizer;
  static Gl& Get() {
    static Gl gl = [] {
      Gl g;
      // GVD_EGL_DEVICE (auto, hardware or software; default auto) picks the EGL device.
      const char* name = std::getenv("GVD_EGL_DEVICE");
      auto preference = ParseDevicePreference(name && *name ? name : "auto");
      if (!preference.ok()) return g;
      auto c = GlContext::Create(*preference);
      if (!c.ok()) return g;
      g.context = std::move(*c);
      g.rasterizer = std::move(*Rasterizer::Create(g.context->info()));
      return g;
    }();
    return gl;
  }
};

}  // namespace gvd

// A GoogleTest fixture with one EGL context and rasterizer per suite (llvmpipe when there is
// no GPU). When no context can be made, tests fail if the environment variable
// GVD_REQUIRE_GL is set (CI sets it) and skip, saying why, otherwise.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

#include "render/gl/context.h"
#include "render/gl/rasterizer.h"
#include "render/gl/scene_raster.h"

namespace gvd {

inline constexpr RenderMode kModes[] = {RenderMode::kMesh, RenderMode::kExact};
inline const char* Name(RenderMode m) { return m == RenderMode::kMesh ? "mesh" : "exact"; }
inline constexpr FullRender kPaths[] = {FullRender::kRaster, FullRender::kCompute};
inline const char* Name(FullRender p) {
  return p == FullRender::kAuto ? "auto" : p == FullRender::kRaster ? "raster" : "compute";
}

class GlTest : public ::testing::Test {
 protected:
  // GVD_EGL_DEVICE (auto, hardware or software; default auto) picks the EGL device, so that
  // a GPU run (tests/bench/gpu.sh) fails instead of falling back to llvmpipe.
  static void SetUpTestSuite() {
    const char* device = std::getenv("GVD_EGL_DEVICE");
    auto preference = ParseDevicePreference(device && *device ? device : "auto");
    if (!preference.ok()) {
      skip_reason_ = new std::string(preference.status().ToString());
      return;
    }
    auto ctx = GlContext::Create(*preference);
    if (!ctx.ok()) {
      skip_reason_ = new std::string(ctx.status().ToString());
      return;
    }
    context_ = ctx->release();
    auto r = Rasterizer::Create(context_->info());
    ASSERT_TRUE(r.ok()) << r.status();
    rasterizer_ = r->release();
  }
  static void TearDownTestSuite() {
    delete rasterizer_;
    delete context_;
    rasterizer_ = nullptr;
    context_ = nullptr;
  }
  void SetUp() override {
    if (context_ != nullptr) return;
    const char* required = std::getenv("GVD_REQUIRE_GL");
    if (required != nullptr && *required != '\0' && std::string(required) != "0") {
      FAIL() << "no EGL context, and GVD_REQUIRE_GL is set: " << *skip_reason_;
    }
    GTEST_SKIP() << "no EGL context: " << *skip_reason_;
  }

  // A render from scratch of the sites (slot i = sites[i]), eps one pixel, at version 1.
  std::shared_ptr<const Frame> Render(const Grid& grid, const SiteTable& sites,
                                      RenderMode mode = RenderMode::kMesh,
                                      Diagram diagram = Diagram::kNearest,
                                      FullRender path = FullRender::kAuto) {
    auto frame = RenderOnce(*rasterizer_, grid, grid.pixel_size(), 1, sites, nullptr, mode,
                            diagram, path);
    EXPECT_TRUE(frame.ok()) << frame.status();
    return frame.ok() ? *frame : nullptr;
  }

  static inline GlContext* context_ = nullptr;
  static inline Rasterizer* rasterizer_ = nullptr;
  static inline std::string* skip_reason_ = nullptr;
};

}  // namespace gvd

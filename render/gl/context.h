// A headless OpenGL 4.5 core context through EGL, with no window system: the render thread's
// only link to the GPU (or to Mesa's software rasterizer when there is none).
#pragma once

#include <memory>
#include <string>

#include "absl/status/statusor.h"

namespace gvd {

enum class DevicePreference {
  kAuto,      // hardware EGL devices first, then software devices, then surfaceless Mesa
  kHardware,  // hardware devices only
  kSoftware,  // software devices and surfaceless Mesa only
};

// Parses "auto", "hardware" or "software".
absl::StatusOr<DevicePreference> ParseDevicePreference(const std::string& name);

struct DeviceInfo {
  std::string platform;    // "device" (EGL_EXT_platform_device) or "surfaceless"
  int device_index = -1;   // into eglQueryDevicesEXT's list; -1 for surfaceless
  bool software = false;   // Mesa's software rasterizer (EGL_MESA_device_software / llvmpipe)
  std::string device_extensions;
  std::string drm_node;    // empty when the device has none
  std::string gl_vendor, gl_renderer, gl_version;
  std::string Describe() const;  // one line for the log
};

// Owns an EGL display and context. Not thread-safe: GL contexts are current on one thread at
// a time, so a single thread creates, uses and destroys it.
class GlContext {
 public:
  // Creates a context and makes it current on the calling thread. The error names each
  // candidate tried, the EGL call that failed and the EGL error.
  static absl::StatusOr<std::unique_ptr<GlContext>> Create(DevicePreference preference);
  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  const DeviceInfo& info() const { return info_; }

 private:
  GlContext(void* display, void* context, DeviceInfo info)
      : display_(display), context_(context), info_(std::move(info)) {}
  void* display_;  // EGLDisplay
  void* context_;  // EGLContext
  DeviceInfo info_;
};

}  // namespace gvd

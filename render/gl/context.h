// A headless OpenGL 4.5 core context through EGL, with no window system: the render thread's
// only link to the GPU (or to Mesa's software rasterizer when there is none).
#pragma once

#include <memory>
#include <mutex>
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

// A thread's turn at GL on a device whose contexts must not be used at once. Mesa's software
// rasterizer (llvmpipe) serves every context of a display from one screen, and a context's
// flush of a resource (before a map or a read-back) reads the queued work of every other
// context of that screen while their own threads change it: two render threads, each with a
// context of its own, crashed there (a freed list read in lp_scene_is_resource_referenced).
// So on a software device the threads that make GL calls take turns, each holding the turn
// around its calls and giving it up around CPU-only work; on a hardware device the turn is
// always free. Not thread-safe: one per thread.
class GlTurn {
 public:
  explicit GlTurn(const DeviceInfo& device);
  ~GlTurn() { Give(); }
  GlTurn(const GlTurn&) = delete;
  GlTurn& operator=(const GlTurn&) = delete;

  void Take();  // waits for the turn, unless held already
  void Give();  // gives it up, if held
  bool held() const { return lock_.owns_lock(); }

  // For its lifetime, the turn given up where `turn` (may be null) holds it; taken back at
  // its end. Around CPU-only work between GL calls.
  class Away {
   public:
    explicit Away(GlTurn* turn) : turn_(turn != nullptr && turn->held() ? turn : nullptr) {
      if (turn_) turn_->Give();
    }
    ~Away() {
      if (turn_) turn_->Take();
    }
    Away(const Away&) = delete;
    Away& operator=(const Away&) = delete;

   private:
    GlTurn* const turn_;
  };

 private:
  std::unique_lock<std::mutex> lock_;  // on software devices, the process's one turn
};

}  // namespace gvd

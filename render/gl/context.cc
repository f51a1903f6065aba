#include "render/gl/context.h"

#define EGL_EGLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES
#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GL/glcorearb.h>

#include <cstring>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace gvd {
namespace {

const char* EglErrorName(EGLint e) {
  switch (e) {
    case EGL_SUCCESS: return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_CURRENT_SURFACE: return "EGL_BAD_CURRENT_SURFACE";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_SURFACE: return "EGL_BAD_SURFACE";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
    case EGL_BAD_NATIVE_PIXMAP: return "EGL_BAD_NATIVE_PIXMAP";
    case EGL_BAD_NATIVE_WINDOW: return "EGL_BAD_NATIVE_WINDOW";
    case EGL_CONTEXT_LOST: return "EGL_CONTEXT_LOST";
    default: return "unknown EGL error";
  }
}

std::string EglFailure(const char* call) {
  EGLint e = eglGetError();
  return absl::StrCat(call, " failed: ", EglErrorName(e), " (0x", absl::Hex(e), ")");
}

bool HasExtension(const char* list, const char* name) {
  if (list == nullptr) return false;
  size_t n = std::strlen(name);
  for (const char* p = std::strstr(list, name); p != nullptr; p = std::strstr(p + n, name)) {
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  }
  return false;
}

struct Candidate {
  EGLenum platform;
  void* native;  // EGLDeviceEXT, or EGL_DEFAULT_DISPLAY for surfaceless
  DeviceInfo info;
};

struct EglHandles {
  EGLDisplay display;
  EGLContext context;
};

// Initializes `c`, makes an OpenGL 4.5 core context current and fills c.info's GL strings;
// on failure, tears down what it made and says why.
absl::StatusOr<EglHandles> TryCandidate(Candidate& c) {
  EGLDisplay display = eglGetPlatformDisplay(c.platform, c.native, nullptr);
  if (display == EGL_NO_DISPLAY) return absl::UnavailableError(EglFailure("eglGetPlatformDisplay"));
  EGLint major = 0, minor = 0;
  if (!eglInitialize(display, &major, &minor)) {
    return absl::UnavailableError(EglFailure("eglInitialize"));
  }
  auto fail = [&](const char* call) {
    std::string msg = EglFailure(call);
    eglTerminate(display);
    return absl::UnavailableError(msg);
  };
  const char* exts = eglQueryString(display, EGL_EXTENSIONS);
  if (!HasExtension(exts, "EGL_KHR_surfaceless_context")) {
    eglTerminate(display);
    return absl::UnavailableError("display lacks EGL_KHR_surfaceless_context");
  }
  if (!eglBindAPI(EGL_OPENGL_API)) return fail("eglBindAPI(EGL_OPENGL_API)");
  EGLConfig config = EGL_NO_CONFIG_KHR;
  if (!HasExtension(exts, "EGL_KHR_no_config_context") &&
      !HasExtension(exts, "EGL_MESA_configless_context")) {
    const EGLint want[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE, EGL_PBUFFER_BIT,
                           EGL_NONE};
    EGLint n = 0;
    if (!eglChooseConfig(display, want, &config, 1, &n) || n == 0) return fail("eglChooseConfig");
  }
  const EGLint attrs[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5,
                          EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                          EGL_NONE};
  EGLContext context = eglCreateContext(display, config, EGL_NO_CONTEXT, attrs);
  if (context == EGL_NO_CONTEXT) return fail("eglCreateContext(OpenGL 4.5 core)");
  if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
    std::string msg = EglFailure("eglMakeCurrent");
    eglDestroyContext(display, context);
    eglTerminate(display);
    return absl::UnavailableError(msg);
  }
  auto str = [](GLenum e) {
    const GLubyte* s = glGetString(e);
    return s ? std::string(reinterpret_cast<const char*>(s)) : std::string();
  };
  c.info.gl_vendor = str(GL_VENDOR);
  c.info.gl_renderer = str(GL_RENDERER);
  c.info.gl_version = str(GL_VERSION);
  if (c.info.gl_renderer.find("llvmpipe") != std::string::npos ||
      c.info.gl_renderer.find("softpipe") != std::string::npos) {
    c.info.software = true;
  }
  return EglHandles{display, context};
}

}  // namespace

absl::StatusOr<DevicePreference> ParseDevicePreference(const std::string& name) {
  if (name == "auto") return DevicePreference::kAuto;
  if (name == "hardware") return DevicePreference::kHardware;
  if (name == "software") return DevicePreference::kSoftware;
  return absl::InvalidArgumentError(
      absl::StrCat("device preference must be auto, hardware or software, not \"", name, "\""));
}

std::string DeviceInfo::Describe() const {
  return absl::StrCat("platform=", platform, " device_index=", device_index,
                      " software=", software ? "true" : "false", " drm_node=\"", drm_node,
                      "\" gl_renderer=\"", gl_renderer, "\" gl_version=\"", gl_version,
                      "\" gl_vendor=\"", gl_vendor, "\"");
}

absl::StatusOr<std::unique_ptr<GlContext>> GlContext::Create(DevicePreference preference) {
  const char* client_exts = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  std::vector<Candidate> hardware, software;

  if (HasExtension(client_exts, "EGL_EXT_device_enumeration") &&
      HasExtension(client_exts, "EGL_EXT_platform_device")) {
    auto query_devices =
        reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
    auto query_string = reinterpret_cast<PFNEGLQUERYDEVICESTRINGEXTPROC>(
        eglGetProcAddress("eglQueryDeviceStringEXT"));
    EGLint count = 0;
    if (query_devices && query_string && query_devices(0, nullptr, &count) && count > 0) {
      std::vector<EGLDeviceEXT> devices(count);
      query_devices(count, devices.data(), &count);
      for (EGLint i = 0; i < count; ++i) {
        Candidate c{EGL_PLATFORM_DEVICE_EXT, devices[i], {}};
        c.info.platform = "device";
        c.info.device_index = i;
        const char* de = query_string(devices[i], EGL_EXTENSIONS);
        c.info.device_extensions = de ? de : "";
        if (HasExtension(de, "EGL_EXT_device_drm")) {
          const char* node = query_string(devices[i], EGL_DRM_DEVICE_FILE_EXT);
          if (node) c.info.drm_node = node;
        }
        c.info.software = HasExtension(de, "EGL_MESA_device_software");
        (c.info.software ? software : hardware).push_back(std::move(c));
      }
    }
  }
  if (HasExtension(client_exts, "EGL_MESA_platform_surfaceless")) {
    Candidate c{EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, {}};
    c.info.platform = "surfaceless";
    software.push_back(std::move(c));
  }

  std::vector<Candidate*> order;
  if (preference != DevicePreference::kSoftware) {
    for (auto& c : hardware) order.push_back(&c);
  }
  if (preference != DevicePreference::kHardware) {
    for (auto& c : software) order.push_back(&c);
  }

  std::vector<std::string> tried;
  for (Candidate* c : order) {
    std::string name = c->info.platform == "device"
                           ? absl::StrCat("EGL device ", c->info.device_index,
                                          c->info.software ? " (software)" : " (hardware)")
                           : std::string("surfaceless Mesa platform");
    auto handles = TryCandidate(*c);
    if (handles.ok()) {
      return std::unique_ptr<GlContext>(
          new GlContext(handles->display, handles->context, std::move(c->info)));
    }
    tried.push_back(absl::StrCat(name, ": ", handles.status().message()));
  }
  if (tried.empty()) {
    return absl::UnavailableError(absl::StrCat(
        "no EGL device or surfaceless platform to try (client extensions: \"",
        client_exts ? client_exts : "none; is libEGL from libglvnd installed?", "\")"));
  }
  return absl::UnavailableError(
      absl::StrCat("no OpenGL 4.5 core context could be made; tried ", absl::StrJoin(tried, "; ")));
}

GlContext::~GlContext() {
  EGLDisplay display = display_;
  eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  eglDestroyContext(display, context_);
  eglTerminate(display);
}

GlTurn::GlTurn(const DeviceInfo& device) {
  static std::mutex software_turn;
  if (device.software) lock_ = std::unique_lock<std::mutex>(software_turn, std::defer_lock);
}

void GlTurn::Take() {
  if (lock_.mutex() != nullptr && !lock_.owns_lock()) lock_.lock();
}

void GlTurn::Give() {
  if (lock_.owns_lock()) lock_.unlock();
}

}  // namespace gvd

#include "client/cli/field_image.h"

#include <dlfcn.h>

#include "absl/strings/str_cat.h"
#include "gvd_modules.h"

namespace gvd::cli {
namespace {

struct Module {
  decltype(&gvd_write_field) write = nullptr;
  std::string error;
};

// The module, loaded once.
Module Load() {
  Module m;
  void* module = OpenModule("libgvd_field_image.so", &m.error);
  if (module) m.write = reinterpret_cast<decltype(&gvd_write_field)>(dlsym(module, "gvd_write_field"));
  if (module && !m.write) m.error = dlerror();
  return m;
}

}  // namespace

absl::Status WriteField(const std::string& path, uint32_t w, uint32_t h, const float* v) {
  static const Module module = Load();
  if (!module.write) {
    return absl::InternalError(absl::StrCat("writing ", path, " needs gvd's field module: ", module.error));
  }
  return module.write(path, w, h, v);
}

}  // namespace gvd::cli

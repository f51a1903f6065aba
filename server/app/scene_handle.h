// One handle over a scene of either dimension, as the application core holds its scenes: a 2D
// scene (Scene) or a 3D one (Scene3). What every scene has is here; what depends on the
// dimension is one Visit into the templates on the scene (jobs, conversions, renders).
#pragma once

#include <memory>
#include <string>
#include <type_traits>
#include <utility>
#include <variant>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "render/scene/scene.h"

namespace gvd {

// f(std::type_identity<S>()) with S the scene type of the settings' dimension: where a scene
// of either dimension is made.
template <class F>
decltype(auto) ForDimension(const SceneSettings& settings, F&& f) {
  if (settings.three_d()) return f(std::type_identity<Scene3>());
  return f(std::type_identity<Scene>());
}

// A shared reference to a scene; copies refer to the same scene. Thread-safe as the scene is.
class SceneHandle {
 public:
  template <class S>
  SceneHandle(std::shared_ptr<S> scene) : scene_(std::move(scene)) {}  // NOLINT: a scene is one

  // f(scene), the scene as a std::shared_ptr of its own type.
  template <class F>
  decltype(auto) Visit(F&& f) const {
    return std::visit(std::forward<F>(f), scene_);
  }
  // The scene as S, or FAILED_PRECONDITION naming both dimensions when it is the other one.
  template <class S>
  absl::StatusOr<std::shared_ptr<S>> As() const {
    if (const auto* s = std::get_if<std::shared_ptr<S>>(&scene_)) return *s;
    constexpr bool kWants3 = S::Kernel::kDimension == 3;
    return absl::FailedPreconditionError(
        absl::StrCat("scene \"", id(), "\" is a ", kWants3 ? "2D" : "3D",
                     " scene; this call needs a ", kWants3 ? "3D" : "2D", " one"));
  }
  bool three_d() const { return scene_.index() == 1; }

  const std::string& id() const { return settings().id; }
  const SceneSettings& settings() const {
    return Visit([](const auto& s) -> const SceneSettings& { return s->settings(); });
  }
  uint64_t version() const {
    return Visit([](const auto& s) { return s->version(); });
  }
  // The version of the latest published frame (a 3D scene's volume).
  uint64_t frame_version() const {
    return Visit([](const auto& s) { return s->frame()->version(); });
  }
  size_t site_count() const {
    return Visit([](const auto& s) { return s->site_count(); });
  }
  uint64_t memory_bytes() const {
    return Visit([](const auto& s) { return s->memory_bytes(); });
  }
  double frame_age_seconds() const {
    return Visit([](const auto& s) { return s->frame_age_seconds(); });
  }
  double render_seconds() const {
    return Visit([](const auto& s) { return s->render_seconds(); });
  }
  bool deleted() const {
    return Visit([](const auto& s) { return s->deleted(); });
  }
  // BasicScene's: the waiters of its frames, and its deletion.
  uint64_t waiter_mark() const {
    return Visit([](const auto& s) { return s->waiter_mark(); });
  }
  void FailWaiters(const absl::Status& status) const {
    Visit([&](const auto& s) { s->FailWaiters(status); });
  }
  void FailWaitersBeyond(uint64_t version, uint64_t mark, const absl::Status& status) const {
    Visit([&](const auto& s) { s->FailWaitersBeyond(version, mark, status); });
  }

  // The same scene object.
  bool operator==(const SceneHandle& other) const { return scene_ == other.scene_; }

 private:
  std::variant<std::shared_ptr<Scene>, std::shared_ptr<Scene3>> scene_;
};

}  // namespace gvd

#include "render/plan/volume_renderer.h"

#include <chrono>
#include <utility>

namespace gvd {

VolumeRenderer::VolumeRenderer(Observer observer)
    : observer_(std::move(observer)), thread_([this] { Run(); }) {}

VolumeRenderer::~VolumeRenderer() { Stop(); }

void VolumeRenderer::MarkDirty(std::shared_ptr<Scene3> scene) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (!stopping_) {
      if (queued_.insert(scene.get()).second) queue_.push_back(std::move(scene));
      cv_.notify_one();
      return;
    }
  }
  scene->FailWaiters(absl::UnavailableError("the server is stopping; no more 3D renders"));
}

void VolumeRenderer::Stop() {
  std::deque<std::shared_ptr<Scene3>> left;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (stopping_ && !thread_.joinable()) return;
    stopping_ = true;
    left.swap(queue_);
    queued_.clear();
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  for (auto& scene : left) {
    scene->FailWaiters(absl::UnavailableError("the server is stopping; no more 3D renders"));
  }
}

void VolumeRenderer::RenderNow(Scene3& scene, const Observer& observer) {
  const auto started = std::chrono::steady_clock::now();
  auto snapshot = scene.snapshot();
  auto base = scene.frame();
  if (base->version() >= snapshot->version()) return;  // rendered already
  VolumeScanStats stats;
  // A first render, from a volume of no sites, is a full one; later ones follow the change.
  auto volume = base->empty() ? ScanVolume(base->grid(), base->diagram(), snapshot, &stats)
                              : UpdateVolume(*base, snapshot, &stats);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  scene.AddRenderSeconds(seconds);
  if (observer) observer(scene, volume->version(), stats, seconds);
  scene.Publish(std::move(volume));
}

void VolumeRenderer::Run() {
  for (;;) {
    std::shared_ptr<Scene3> scene;
    {
      std::unique_lock<std::mutex> lock(mu_);
      cv_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
      if (stopping_) return;
      scene = std::move(queue_.front());
      queue_.pop_front();
      queued_.erase(scene.get());
    }
    // A scene deleted meanwhile is not rendered; its waiters were failed by its deletion.
    if (!scene->deleted()) RenderNow(*scene, observer_);
  }
}

}  // namespace gvd

#include "render/gl/render_loop.h"

#include <pthread.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <future>
#include <map>
#include <set>
#include <utility>

#include "absl/cleanup/cleanup.h"
#include "absl/strings/str_cat.h"
#include "render/gl/rasterizer.h"
#include "render/gl/scene_raster.h"
#include "render/scene/cpu_pool.h"

namespace gvd {

RenderLoop::~RenderLoop() { Stop(); }

absl::Status RenderLoop::Start(DevicePreference preference) {
  if (const char* hold = std::getenv(kHoldRendersVariable)) hold_path_ = hold;
  // The CPU pools are made here, not by the first render: made by a render thread, the
  // process's pool would inherit its nice value, and it answers queries too.
  CpuPool::Process();
  CpuPool::Renders();
  // A caller that begins to wait ends the lanes' rests.
  waker_ = RenderWait::WakeOnCaller([this] {
    std::lock_guard<std::mutex> lock(mu_);
    WakeAll();
  });
  for (int lane = 0; lane < lanes_; ++lane) {
    threads_.emplace_back([this, lane, preference] { Run(lane, preference); });
  }
  absl::Status status;
  {
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait(lock, [this] { return started_ == lanes_; });
    status = start_status_;
  }
  if (!status.ok()) Stop();
  return status;
}

void RenderLoop::Stop() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stopping_ = true;
    WakeAll();
  }
  for (std::thread& t : threads_) {
    if (t.joinable()) t.join();
  }
  if (waker_ != 0) RenderWait::StopWaking(std::exchange(waker_, 0));
}

void RenderLoop::MarkDirty(std::shared_ptr<Scene> scene) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (!stopping_) {
      const Scene* queued = scene.get();
      if (!dirty_.Push(std::move(scene))) return;  // queued already: a lane will take it
      // A watched scene ends the lanes' rests.
      if (queued->watched()) return WakeAll();
      // Being rendered: its lane takes it again after this render.
      if (dirty_.rendering(queued)) return;
      // Its own lane, unless that lane is busy; then, as for a scene of nobody's, the first
      // lane that sleeps. A lane that rests or is on its way back takes it when it looks.
      if (auto owner = owner_.find(queued); owner != owner_.end() && !busy_[owner->second]) {
        return Wake(owner->second);
      }
      for (int lane = 0; lane < lanes_; ++lane) {
        if (waiting_[lane]) return Wake(lane);
      }
      return;
    }
  }
  scene->FailWaiters(absl::UnavailableError("the server is shutting down"));
}

bool RenderLoop::Enqueue(Task task) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (stopping_ || started_ < lanes_ || !start_status_.ok()) return false;
    tasks_.push_back(std::move(task));
    WakeAll();
  }
  return true;
}

absl::StatusOr<std::vector<std::shared_ptr<const Frame>>> RenderLoop::RenderWindows(
    std::shared_ptr<const Frame> base, RenderMode mode, std::vector<Grid> grids) {
  std::promise<absl::StatusOr<std::vector<std::shared_ptr<const Frame>>>> done;
  auto result = done.get_future();
  RenderWait waiting;  // the caller waits for the render thread
  const bool queued = Enqueue([&, base = std::move(base), grids = std::move(grids)](
                                  Rasterizer* rasterizer, ZoomRenderer* zoom) {
    if (rasterizer == nullptr) {
      done.set_value(absl::UnavailableError("the server is shutting down"));
      return;
    }
    done.set_value(zoom->Render(*rasterizer, *base, mode, grids));
  });
  if (!queued) return absl::UnavailableError("the render thread is not running");
  return result.get();
}

absl::StatusOr<std::shared_ptr<const Frame>> RenderLoop::RenderSites(
    std::shared_ptr<const SiteSnapshot> sites, Grid grid, double eps, RenderMode mode,
    Diagram diagram) {
  std::promise<absl::StatusOr<std::shared_ptr<const Frame>>> done;
  auto result = done.get_future();
  RenderWait waiting;  // the caller waits for the render thread
  const bool queued = Enqueue([&, sites = std::move(sites)](Rasterizer* rasterizer, ZoomRenderer*) {
    if (rasterizer == nullptr) {
      done.set_value(absl::UnavailableError("the server is shutting down"));
      return;
    }
    auto raster = SceneRaster::Create(grid, eps, mode, diagram);
    if (!raster.ok()) {
      done.set_value(raster.status());
      return;
    }
    done.set_value((*raster)->Apply(*rasterizer, sites));
  });
  if (!queued) return absl::UnavailableError("the render thread is not running");
  return result.get();
}

std::shared_ptr<Scene> RenderLoop::Take(int lane) {
  std::shared_ptr<Scene> taken = dirty_.TakeFirst([&](const Scene* scene) {
    if (dirty_.rendering(scene)) return false;
    auto owner = owner_.find(scene);
    return owner == owner_.end() || owner->second == lane || busy_[owner->second];
  });
  if (!taken) return nullptr;
  const Scene* scene = taken.get();
  if (auto owner = owner_.find(scene); owner != owner_.end() && owner->second != lane) {
    taken_from_[owner->second].push_back(scene);
  }
  owner_[scene] = lane;
  busy_[lane] = true;
  // The other lanes may take this lane's scenes now, which they turned down while it was
  // free: without a word they would sleep until the next update or render's end, and this
  // render may go on for seconds.
  if (!dirty_.empty()) WakeSleeping();
  return taken;
}

void RenderLoop::Wake(int lane) {
  if (!waiting_[lane]) return;
  // Not waiting from now on, so that the next scene marked before this lane wakes goes to
  // another lane.
  waiting_[lane] = false;
  wake_[lane].notify_one();
}

void RenderLoop::WakeSleeping() {
  for (int lane = 0; lane < lanes_; ++lane) Wake(lane);
}

void RenderLoop::WakeAll() {
  for (int lane = 0; lane < lanes_; ++lane) {
    waiting_[lane] = false;
    wake_[lane].notify_one();
  }
}

void RenderLoop::Run(int lane, DevicePreference preference) {
  // Calls come before renders (RenderWait), the render's ParallelFor pieces included.
  pthread_setname_np(pthread_self(), "gvd-render");
  CpuPool::BecomeRenderThread();
  // This lane's turn at GL (GlTurn: on a software device one lane at a time makes GL calls).
  std::unique_ptr<GlTurn> turn;
  std::unique_ptr<GlContext> context;
  std::unique_ptr<Rasterizer> rasterizer;
  {
    absl::Status status;
    auto ctx = GlContext::Create(preference);
    if (ctx.ok()) {
      context = std::move(*ctx);
      turn = std::make_unique<GlTurn>(context->info());
      turn->Take();
      auto r = Rasterizer::Create(context->info());
      turn->Give();
      if (r.ok()) {
        rasterizer = std::move(*r);
        rasterizer->set_gl_turn(turn.get());
      } else {
        status = r.status();
      }
    } else {
      status = ctx.status();
    }
    // The driver's threads are made: from here on, renders nobody waits for run in the
    // background.
    CpuPool::RenderInBackground();
    std::lock_guard<std::mutex> lock(mu_);
    if (context && lane == 0) device_ = context->info();
    if (!status.ok() && start_status_.ok()) start_status_ = status;
    ++started_;
    cv_.notify_all();
    if (!status.ok()) return;
  }

  // One SceneRaster (GPU buffers and incremental state) per scene this lane holds, kept
  // between renders; released when the scene is deleted, taken over by another lane, or a
  // render fails.
  std::map<const Scene*, std::pair<std::weak_ptr<Scene>, std::unique_ptr<SceneRaster>>> rasters;
  ZoomRenderer zoom;
  // Ends this lane's turn on a scene: another lane may take it (or one this lane left) now.
  auto finish = [&](const Scene* scene) {
    std::lock_guard<std::mutex> lock(mu_);
    dirty_.Rendered(scene);
    busy_[lane] = false;
    if (!dirty_.empty()) WakeSleeping();
  };
  while (true) {
    std::shared_ptr<Scene> scene;
    std::deque<Task> tasks;
    std::set<const Scene*> mine;
    std::vector<const Scene*> dropped;
    {
      std::unique_lock<std::mutex> lock(mu_);
      while (!stopping_ && tasks_.empty() && taken_from_[lane].empty() &&
             !(scene = Take(lane))) {
        waiting_[lane] = true;  // until a Wake clears it
        wake_[lane].wait(lock);
        waiting_[lane] = false;
      }
      if (stopping_) {
        if (scene) {
          dirty_.PushFront(std::move(scene));  // its waiters fail with the rest below
        }
        break;
      }
      tasks.swap(tasks_);
      for (const auto& [s, owner] : owner_) {
        if (owner == lane) mine.insert(s);
      }
      dropped.swap(taken_from_[lane]);
    }
    // GL from here to the end of this round, but around the waits below.
    turn->Take();
    absl::Cleanup give_turn = [&turn] { turn->Give(); };
    // Scenes another lane took over: their GPU state goes now, not at this lane's next render.
    for (const Scene* s : dropped) {
      if (!mine.count(s)) rasters.erase(s);
    }
    // Zooms first (they are small, and a caller waits on each), then one scene.
    for (auto& task : tasks) task(rasterizer.get(), &zoom);
    if (!scene) continue;
    if (!hold_path_.empty() && access(hold_path_.c_str(), F_OK) == 0) {
      // Held (kHoldRendersVariable): the scene goes back to the front of the queue, and the
      // loop looks again shortly, still taking zooms and a stop meanwhile.
      turn->Give();
      std::unique_lock<std::mutex> lock(mu_);
      busy_[lane] = false;
      dirty_.PushFront(std::move(scene));
      wake_[lane].wait_for(lock, std::chrono::milliseconds(5),
                           [this] { return stopping_ || !tasks_.empty(); });
      continue;
    }
    // Drop the state of scenes that are gone or that another lane took over.
    for (auto it = rasters.begin(); it != rasters.end();) {
      auto owner = it->second.first.lock();
      it = (!owner || owner->deleted() || !mine.count(it->first)) ? rasters.erase(it) : std::next(it);
    }
    if (scene->deleted()) {
      {
        std::lock_guard<std::mutex> lock(mu_);
        owner_.erase(scene.get());
      }
      finish(scene.get());
      continue;
    }
    const SceneSettings& settings = scene->settings();
    auto start = std::chrono::steady_clock::now();
    auto& slot = rasters[scene.get()];
    absl::StatusOr<std::shared_ptr<const Frame>> frame;
    if (!slot.second) {
      auto raster = SceneRaster::Create(settings.grid, settings.eps, settings.mode,
                                        settings.diagram);
      if (raster.ok()) {
        slot = {scene, std::move(*raster)};
      } else {
        frame = raster.status();
      }
    }
    // The newest snapshot: the raster draws what differs from the one it drew last.
    std::shared_ptr<const SiteSnapshot> sites = scene->snapshot();
    if (slot.second && sites->version() <= scene->frame()->version()) {
      finish(scene.get());
      continue;
    }
    RenderStats render_stats;
    // The test hook's long render of this one scene (kHoldRendersVariable): a full render
    // waits in its plan, where it has given up its turn at GL. Set for this render alone:
    // zooms and other scenes' renders do not wait.
    if (!hold_path_.empty()) {
      rasterizer->set_planning_hook([this, lane, held = hold_path_ + "." + scene->id()] {
        if (access(held.c_str(), F_OK) != 0) return;
        const std::string waiting = held + ".waiting";
        if (FILE* f = std::fopen(waiting.c_str(), "w")) std::fclose(f);
        while (access(held.c_str(), F_OK) == 0) {
          std::unique_lock<std::mutex> lock(mu_);
          if (wake_[lane].wait_for(lock, std::chrono::milliseconds(5),
                                   [this] { return stopping_; })) {
            break;
          }
        }
        std::remove(waiting.c_str());
      });
    }
    if (slot.second) frame = slot.second->Apply(*rasterizer, sites, &render_stats);
    rasterizer->set_planning_hook(nullptr);
    double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (!frame.ok()) {
      rasters.erase(scene.get());  // the next render starts from scratch
      turn->Give();
      if (observer_) observer_->Failed(scene->id(), sites->version(), frame.status());
      scene->FailWaiters(absl::UnavailableError(
          absl::StrCat("rendering scene \"", scene->id(), "\" failed: ", frame.status().message())));
      finish(scene.get());
      continue;
    }
    turn->Give();  // the GL work of this round is done
    // Reported before publishing: publishing releases the queries waiting for this frame.
    if (observer_) {
      observer_->Rendered(scene->id(), sites->version(), sites->size(), render_stats, seconds);
    }
    scene->AddRenderSeconds(seconds);
    // Whether anybody awaited this frame or watches the scene, told before publishing
    // releases the waiters and tells the listeners.
    const bool background = RenderWait::callers() == 0 && !scene->watched();
    scene->Publish(*frame);
    finish(scene.get());
    // A render nobody waited for or watches: the lane rests (see MarkDirty).
    if (background_rest_ > 0 && background) {
      const auto until = std::chrono::steady_clock::now() +
                         std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                             std::chrono::duration<double>(seconds * background_rest_));
      std::unique_lock<std::mutex> lock(mu_);
      wake_[lane].wait_until(lock, until, [this] {
        return stopping_ || RenderWait::callers() > 0 || dirty_.Any([](const Scene* s) {
                 return s->watched();
               });
      });
    }
  }

  // Whatever is still queued will not be rendered: release its waiters.
  std::deque<std::shared_ptr<Scene>> left;
  std::deque<Task> tasks;
  {
    std::lock_guard<std::mutex> lock(mu_);
    left = dirty_.TakeAll();
    tasks.swap(tasks_);
  }
  for (auto& s : left) s->FailWaiters(absl::UnavailableError("the server is shutting down"));
  for (auto& task : tasks) task(nullptr, nullptr);
  turn->Take();
  rasters.clear();
  rasterizer.reset();
  context.reset();
  turn->Give();
}

}  // namespace gvd

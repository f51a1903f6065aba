// The service's calls on the structure of a diagram and its applications (paper sec. 5-7):
// boundaries, neighbours, Delaunay, zoom windows, clearance, planning and mosaics. Each waits
// for its frame like a query (a mosaic has no scene), then works on the analyses lane (never
// on a transport's thread), rendering zoom windows through the renderer when it needs them.
#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <unordered_map>

#include "absl/strings/str_cat.h"
#include "render/analysis/analysis.h"
#include "render/analysis/clearance3.h"
#include "render/analysis/planning.h"
#include "render/analysis/refine.h"
#include "render/image/mosaic.h"
#include "server/app/convert/analysis.h"
#include "server/app/convert/common.h"
#include "server/app/convert/images.h"
#include "server/app/jobs.h"
#include "server/app/service.h"

namespace gvd {
namespace {

// The id of the site in `slot + 1` (0: no site, the empty string).
const std::string& IdOf(const Frame& frame, uint32_t id) {
  static const std::string kNone;
  return id == 0 ? kNone : frame.sites().get(id - 1)->id;
}

// Zoom windows of `frame` through the render thread; stops once the call is cancelled. The
// refinement of neighbours zooms in EXACT mode whatever the scene's: where four sites are
// nearly equidistant, a mesh's error (even at the zoom's finer eps) blurs which is nearest
// over a band much wider than the structure sought.
ZoomFn Zoomer(SceneRegistry* registry, std::shared_ptr<const Frame> frame, RenderMode mode,
              CallPtr call) {
  return [=](const std::vector<Grid>& grids)
             -> absl::StatusOr<std::vector<std::shared_ptr<const Frame>>> {
    if (call->cancelled()) return absl::CancelledError("the call was cancelled");
    return registry->Zoom(frame, mode, grids);
  };
}

// The frame's neighbour pairs in `rect`, refined through zoom windows unless `coarse`.
absl::StatusOr<RefinedNeighbors> Neighbours(SceneRegistry* registry,
                                            const std::shared_ptr<const Frame>& frame,
                                            PixelRect rect, bool coarse, const CallPtr& call) {
  ZoomFn zoom;
  if (!coarse) zoom = Zoomer(registry, frame, RenderMode::kExact, call);
  return RefineNeighbors(*frame, rect, zoom);
}

// The pixels of the frame a request names: its window (clipped), or all of them.
absl::Status RectOf(bool has_window, const v1::Window& window, const Grid& grid, PixelRect* rect) {
  *rect = grid.all();
  return has_window ? ToPixelRect(window, grid, rect) : absl::OkStatus();
}

// A zoom request: none (the frame's own pixels, over the window when there is one), or a
// window of the plane at width x height.
struct ZoomSpec {
  bool render = false;
  Grid grid;       // when render
  PixelRect rect;  // when not
};

// `pixel_bytes`: the least an answer holds per pixel, to refuse one that cannot fit a message
// before rendering it (0: no such check; an encoded image's size is known once encoded).
absl::Status ToZoomSpec(bool has_window, const v1::Window& window, uint32_t width, uint32_t height,
                        const Grid& scene, const ServerLimits& limits, ZoomSpec* spec,
                        uint64_t pixel_bytes = 10) {
  if (width == 0 && height == 0) return RectOf(has_window, window, scene, &spec->rect);
  spec->render = true;
  spec->grid.window = scene.window;
  if (has_window) {
    if (auto s = ToWindow(window, "window", &spec->grid.window); !s.ok()) return s;
  }
  if (auto s = ToGridSize(width, height, limits, &spec->grid); !s.ok()) return s;
  // Each pixel answers with an id and a float at least.
  if (spec->grid.pixel_count() * pixel_bytes > uint64_t(limits.max_message_bytes)) {
    return absl::ResourceExhaustedError(
        absl::StrCat(width, "x", height, " pixels do not fit in a message of ",
                     limits.max_message_bytes, " bytes (--max-message-bytes)"));
  }
  return absl::OkStatus();
}

// The frame a ZoomSpec asks for, and the rect of it to answer with.
absl::StatusOr<std::pair<std::shared_ptr<const Frame>, PixelRect>> Resolve(
    const ZoomSpec& spec, const std::shared_ptr<const Frame>& frame, RenderMode mode,
    SceneRegistry* registry, const CallPtr& call) {
  if (!spec.render) return std::pair{frame, spec.rect};
  auto zoomed = Zoomer(registry, frame, mode, call)({spec.grid});
  if (!zoomed.ok()) return zoomed.status();
  return std::pair{(*zoomed)[0], spec.grid.all()};
}

// The window covered by `rect` of the grid, out to its pixels' edges.
Window EdgesOf(const Grid& g, PixelRect rect) {
  Window w{g.window.min_x + rect.x0 * g.pixel_width(), g.window.min_y + rect.y0 * g.pixel_height(),
           g.window.min_x + rect.x1 * g.pixel_width(), g.window.min_y + rect.y1 * g.pixel_height()};
  if (rect.x1 == g.width) w.max_x = g.window.max_x;
  if (rect.y1 == g.height) w.max_y = g.window.max_y;
  return w;
}

void AddHidden(const Frame& frame, const RefinedNeighbors& r,
               google::protobuf::RepeatedPtrField<v1::HiddenSite>* out) {
  std::set<uint32_t> recovered(r.recovered.begin(), r.recovered.end());
  for (uint32_t s : r.hidden) {
    v1::HiddenSite* h = out->Add();
    h->set_site_id(frame.sites().get(s)->id);
    h->set_recovered(recovered.count(s) > 0);
  }
}

// Site-id pairs (a < b bytewise) from id pairs, in order.
std::vector<std::pair<std::string, std::string>> NamedPairs(const Frame& frame,
                                                            const NeighborCounts& pairs) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& [p, n] : pairs) {
    const std::string &a = IdOf(frame, p.first), &b = IdOf(frame, p.second);
    out.push_back(a < b ? std::pair{a, b} : std::pair{b, a});
  }
  std::sort(out.begin(), out.end());
  return out;
}

// The scene a structure call works on: 2D (FAILED_PRECONDITION naming the scene otherwise).
absl::StatusOr<std::shared_ptr<Scene>> PlaneOf(const std::optional<SceneHandle>& scene) {
  return scene->As<Scene>();
}

// A NEAREST scene, for clearance and planning.
absl::Status NeedsNearest(const SceneSettings& s, const char* what) {
  if (s.diagram == Diagram::kNearest) return absl::OkStatus();
  return absl::FailedPreconditionError(
      absl::StrCat("scene \"", s.id, "\" is a DIAGRAM_FARTHEST scene; ", what, " needs DIAGRAM_NEAREST"));
}

// GetClearanceField of a 3D scene (S: its type), read off its volume.
template <class S>
void VolumeClearance(SceneRegistry* registry, CallPtr call, const std::shared_ptr<S>& scene,
                     const v1::GetClearanceFieldRequest& request,
                     v1::GetClearanceFieldResponse* response, Done done) {
  if (auto s = NeedsNearest(scene->settings(), "clearance"); !s.ok()) return done(s);
  auto samples = std::make_shared<ClearanceSamples3>();
  if (auto s = ToClearanceSamples3(request, scene->settings().grid3(), scene->site_count(),
                                   registry->limits(), samples.get());
      !s.ok()) {
    return done(s);
  }
  auto version = registry->ReadVersion(*scene, request.min_version());
  if (!version.ok()) return done(version.status());
  const bool gradients = request.gradients(), indices = request.site_indices();
  // Written straight into the response, on the analyses lane and the CPU pool.
  auto work = [=](const std::shared_ptr<const Volume>& volume) -> absl::Status {
    const ClearanceSamples3& at = *samples;
    const int n = static_cast<int>(at.count());
    response->mutable_clearance()->Resize(n, INFINITY);
    float* gradient = nullptr;
    std::vector<uint32_t> slots(indices ? n : 0, 0);  // slot + 1 per sample, 0 none
    if (gradients) {
      response->mutable_gradient()->Resize(3 * n, 0);
      gradient = response->mutable_gradient()->mutable_data();
    }
    ClearanceField3(*volume, at, response->mutable_clearance()->mutable_data(), gradient,
                    indices ? slots.data() : nullptr);
    if (indices) {  // 1 + an index into site_ids, in the order the samples first name them
      response->mutable_ids()->Resize(n, 0);
      uint32_t* ids = response->mutable_ids()->mutable_data();
      std::unordered_map<uint32_t, uint32_t> named;
      for (int s = 0; s < n; ++s) {
        if (slots[s] == 0) continue;
        auto [it, fresh] = named.try_emplace(slots[s], static_cast<uint32_t>(named.size() + 1));
        if (fresh) response->add_site_ids(volume->sites().get(slots[s] - 1)->id);
        ids[s] = it->second;
      }
    }
    response->set_version(volume->version());
    ToProto(at.box, response->mutable_window());
    response->set_width_px(at.width);
    response->set_height_px(at.height);
    response->set_depth_px(at.depth);
    return absl::OkStatus();
  };
  using Job = BasicAnalysisJob<S>;
  auto job =
      Job::Make(registry, scene, *version, std::move(work), [call] { return call->cancelled(); });
  call->OnCancel([weak = std::weak_ptr<Job>(job)] {
    if (auto job = weak.lock()) job->Cancel();
  });
  job->Start(std::move(done));
}

}  // namespace

void Service::StartAnalysis(CallPtr call, const std::shared_ptr<Scene>& scene, uint64_t min_version,
                            FrameWork work, Done done) {
  auto version = registry_->ReadVersion(*scene, min_version);
  if (!version.ok()) return done(version.status());
  auto job = AnalysisJob::Make(
      registry_, scene, *version,
      [scene, work = std::move(work)](const std::shared_ptr<const Frame>& frame) {
        return work(frame, *scene);
      },
      [call] { return call->cancelled(); });
  call->OnCancel([weak = std::weak_ptr<AnalysisJob>(job)] {
    if (auto job = weak.lock()) job->Cancel();
  });
  job->Start(std::move(done));
}

void Service::GetBoundaries(CallPtr call, const v1::GetBoundariesRequest& request,
                            v1::GetBoundariesResponse* response, Done done) {
  Begun begun = Begin(*call, "GetBoundaries", Access::kRead, &request.scene_id());
  done = Ending(begun.scope, std::move(done));
  if (!begun.status.ok()) return done(begun.status);
  auto scene = PlaneOf(begun.scene);
  if (!scene.ok()) return done(scene.status());
  BoundaryMethod method = BoundaryMethod::kFullScan;
  PixelRect rect;
  if (auto s = ToBoundaryMethod(request, &method); !s.ok()) return done(s);
  if (auto s = RectOf(request.has_window(), request.window(), (*scene)->settings().grid, &rect);
      !s.ok()) {
    return done(s);
  }
  StartAnalysis(
      call, *scene, request.min_version(),
      [=](const std::shared_ptr<const Frame>& frame, const Scene&) {
        IdImage image = IdsOf(*frame, rect);
        BoundaryEdges edges = FindBoundaryEdges(image, method);
        for (const BoundaryPolyline& line :
             TraceBoundaries(image, edges, frame->sites(), frame->error().diagram)) {
          v1::Boundary* b = response->add_boundaries();
          const std::string &a = IdOf(*frame, line.a), &c = IdOf(*frame, line.b);
          b->set_site_a(std::min(a, c));
          b->set_site_b(std::max(a, c));
          b->mutable_xy()->Reserve(static_cast<int>(line.points.size() * 2));
          for (Vec2 pt : line.points) {
            b->add_xy(pt.x);
            b->add_xy(pt.y);
          }
          b->set_closed(line.closed);
        }
        response->set_version(frame->version());
        response->set_boundary_pixel_pairs(edges.count);
        response->set_cells_visited(edges.cells_visited);
        return absl::OkStatus();
      },
      std::move(done));
}

void Service::GetNeighbors(CallPtr call, const v1::GetNeighborsRequest& request,
                           v1::GetNeighborsResponse* response, Done done) {
  Begun begun = Begin(*call, "GetNeighbors", Access::kRead, &request.scene_id());
  done = Ending(begun.scope, std::move(done));
  if (!begun.status.ok()) return done(begun.status);
  auto scene = PlaneOf(begun.scene);
  if (!scene.ok()) return done(scene.status());
  PixelRect rect;
  if (auto s = RectOf(request.has_window(), request.window(), (*scene)->settings().grid, &rect);
      !s.ok()) {
    return done(s);
  }
  SceneRegistry* registry = registry_;
  StartAnalysis(
      call, *scene, request.min_version(),
      [=, &request](const std::shared_ptr<const Frame>& frame, const Scene&) {
        const std::string& only = request.site_id();
        if (!only.empty()) {
          bool live = false;
          for (uint32_t s = 0; s < frame->sites().size() && !live; ++s) {
            const Site* site = frame->sites().get(s);
            live = site && site->id == only;
          }
          if (!live) {
            return absl::NotFoundError(absl::StrCat(
                "site_id \"", only, "\" is not in the scene at version ", frame->version()));
          }
        }
        auto r = Neighbours(registry, frame, rect, request.coarse(), call);
        if (!r.ok()) return r.status();
        for (const auto& [a, b] : NamedPairs(*frame, r->pairs)) {
          if (!only.empty() && a != only && b != only) continue;
          v1::NeighborPair* pair = response->add_pairs();
          pair->set_site_a(a);
          pair->set_site_b(b);
        }
        AddHidden(*frame, *r, response->mutable_hidden());
        response->set_version(frame->version());
        response->set_zoom_windows(r->windows);
        response->set_zoom_depth(r->depth);
        return absl::OkStatus();
      },
      std::move(done));
}

void Service::GetDelaunay(CallPtr call, const v1::GetDelaunayRequest& request,
                          v1::GetDelaunayResponse* response, Done done) {
  Begun begun = Begin(*call, "GetDelaunay", Access::kRead, &request.scene_id());
  done = Ending(begun.scope, std::move(done));
  if (!begun.status.ok()) return done(begun.status);
  auto scene = PlaneOf(begun.scene);
  if (!scene.ok()) return done(scene.status());
  SceneRegistry* registry = registry_;
  const bool coarse = request.coarse();
  StartAnalysis(
      call, *scene, request.min_version(),
      [=](const std::shared_ptr<const Frame>& frame, const Scene&) {
        const SlotTable& sites = frame->sites();
        std::vector<Vec2> points(sites.size());
        for (uint32_t s = 0; s < sites.size(); ++s) {
          const Site* site = sites.get(s);
          if (site == nullptr) continue;
          const auto* p = std::get_if<PointSite>(&site->geometry);
          if (p == nullptr) {
            return absl::FailedPreconditionError(
                absl::StrCat("site \"", site->id,
                             "\" is not a point; a Delaunay triangulation needs point "
                             "sites only (GetNeighbors works for every kind)"));
          }
          points[s] = p->p;
        }
        auto r = Neighbours(registry, frame, frame->grid().all(), coarse, call);
        if (!r.ok()) return r.status();
        std::vector<std::pair<uint32_t, uint32_t>> edges;
        for (const auto& [p, n] : r->pairs) edges.push_back({p.first - 1, p.second - 1});
        for (const auto& [a, b] : NamedPairs(*frame, r->pairs)) {
          v1::NeighborPair* e = response->add_edges();
          e->set_site_a(a);
          e->set_site_b(b);
        }
        for (const auto& t : TrianglesFromEdges(points, edges)) {
          v1::Triangle* out = response->add_triangles();
          out->set_a(sites.get(t[0])->id);
          out->set_b(sites.get(t[1])->id);
          out->set_c(sites.get(t[2])->id);
        }
        AddHidden(*frame, *r, response->mutable_hidden());
        response->set_version(frame->version());
        response->set_zoom_windows(r->windows);
        return absl::OkStatus();
      },
      std::move(done));
}

void Service::RenderWindow(CallPtr call, const v1::RenderWindowRequest& request,
                           v1::RenderWindowResponse* response, Done done) {
  Begun begun = Begin(*call, "RenderWindow", Access::kRead, &request.scene_id());
  done = Ending(begun.scope, std::move(done));
  if (!begun.status.ok()) return done(begun.status);
  auto scene = PlaneOf(begun.scene);
  if (!scene.ok()) return done(scene.status());
  ZoomSpec spec;
  if (auto s = ToZoomSpec(request.has_window(), request.window(), request.width_px(),
                          request.height_px(), (*scene)->settings().grid, limits_, &spec);
      !s.ok()) {
    return done(s);
  }
  SceneRegistry* registry = registry_;
  StartAnalysis(
      call, *scene, request.min_version(),
      [=](const std::shared_ptr<const Frame>& frame, const Scene& scene) {
        auto resolved = Resolve(spec, frame, scene.settings().mode, registry, call);
        if (!resolved.ok()) return resolved.status();
        const auto& [f, rect] = *resolved;
        std::map<uint32_t, uint32_t> named;  // id -> index + 1 into site_ids
        auto* ids = response->mutable_ids();
        auto* distances = response->mutable_distances();
        ids->Reserve(static_cast<int>(rect.area()));
        distances->Reserve(static_cast<int>(rect.area()));
        for (uint32_t j = rect.y0; j < rect.y1; ++j) {
          for (uint32_t i = rect.x0; i < rect.x1; ++i) {
            uint32_t id = f->id_at(i, j);
            if (id == 0) {
              ids->Add(0);
              distances->Add(INFINITY);
              continue;
            }
            auto [it, fresh] = named.emplace(id, static_cast<uint32_t>(named.size() + 1));
            if (fresh) response->add_site_ids(IdOf(*f, id));
            ids->Add(it->second);
            distances->Add(f->distance_at(i, j));
          }
        }
        response->set_version(f->version());
        ToProto(EdgesOf(f->grid(), rect), response->mutable_window());
        response->set_width_px(rect.width());
        response->set_height_px(rect.height());
        response->set_max_error(f->error().max_excess);
        return absl::OkStatus();
      },
      std::move(done));
}

void Service::RenderImageAt(CallPtr call, const std::shared_ptr<Scene>& scene,
                            const v1::RenderImageRequest& request,
                            v1::RenderImageResponse* response, Done done) {
  auto spec = std::make_shared<ZoomSpec>();
  auto options = std::make_shared<ImageOptions>();
  if (auto s = ToZoomSpec(request.has_window(), request.window(), request.width_px(),
                          request.height_px(), scene->settings().grid, limits_, spec.get(),
                          /*pixel_bytes=*/0);
      !s.ok()) {
    return done(s);
  }
  // The request's window is the zoom grid's: all of its pixels.
  if (auto s = ToImageOptions(request, spec->grid, options.get()); !s.ok()) return done(s);
  SceneRegistry* registry = registry_;
  const int max_message_bytes = limits_.max_message_bytes;
  StartAnalysis(
      call, scene, request.min_version(),
      [=](const std::shared_ptr<const Frame>& frame, const Scene& scene) {
        auto resolved = Resolve(*spec, frame, scene.settings().mode, registry, call);
        if (!resolved.ok()) return resolved.status();
        const auto& [f, rect] = *resolved;
        options->rect = rect;
        auto image = EncodeImage(*f, *options);
        if (!image.ok()) return image.status();
        response->set_image(image->bytes.data(), image->bytes.size());
        response->set_mime_type(image->mime_type);
        response->set_width_px(image->width);
        response->set_height_px(image->height);
        response->set_version(f->version());
        for (const std::string& id : image->site_ids) response->add_site_ids(id);
        ToProto(EdgesOf(f->grid(), rect), response->mutable_window());
        if (const size_t bytes = response->ByteSizeLong(); bytes > size_t(max_message_bytes)) {
          response->Clear();
          return absl::ResourceExhaustedError(absl::StrCat(
              "the ", options->rect.width(), "x", options->rect.height(), " image's answer is ",
              bytes, " bytes, more than a message holds (--max-message-bytes ", max_message_bytes,
              ")"));
        }
        return absl::OkStatus();
      },
      std::move(done));
}

void Service::GetClearanceField(CallPtr call, const v1::GetClearanceFieldRequest& request,
                                v1::GetClearanceFieldResponse* response, Done done) {
  Begun begun = Begin(*call, "GetClearanceField", Access::kRead, &request.scene_id());
  done = Ending(begun.scope, std::move(done));
  if (!begun.status.ok()) return done(begun.status);
  begun.scene->Visit([&](const auto& scene) {
    using S = std::decay_t<decltype(*scene)>;
    if constexpr (S::Kernel::kDimension == 3) {
      VolumeClearance(registry_, call, scene, request, response, std::move(done));
    } else {
      PlaneClearance(call, scene, request, response, std::move(done));
    }
  });
}

void Service::PlaneClearance(CallPtr call, const std::shared_ptr<Scene>& scene,
                             const v1::GetClearanceFieldRequest& request,
                             v1::GetClearanceFieldResponse* response, Done done) {
  if (request.depth_px() != 0 || request.gradients() || request.site_indices() ||
      request.window().min_z() != 0 || request.window().max_z() != 0) {
    return done(
        Invalid(absl::StrCat("depth_px, window.min_z/max_z, gradients and site_indices "
                             "are for 3D scenes; scene \"",
                             request.scene_id(), "\" is 2D")));
  }
  if (auto s = NeedsNearest(scene->settings(), "clearance"); !s.ok()) return done(s);
  ZoomSpec spec;
  if (auto s = ToZoomSpec(request.has_window(), request.window(), request.width_px(),
                          request.height_px(), scene->settings().grid, limits_, &spec);
      !s.ok()) {
    return done(s);
  }
  SceneRegistry* registry = registry_;
  StartAnalysis(
      call, scene, request.min_version(),
      [=](const std::shared_ptr<const Frame>& frame, const Scene& scene) {
        auto resolved = Resolve(spec, frame, scene.settings().mode, registry, call);
        if (!resolved.ok()) return resolved.status();
        const auto& [f, rect] = *resolved;
        ClearanceField field = MakeClearanceField(*f);
        auto* out = response->mutable_clearance();
        out->Reserve(static_cast<int>(rect.area()));
        for (uint32_t j = rect.y0; j < rect.y1; ++j) {
          for (uint32_t i = rect.x0; i < rect.x1; ++i) out->Add(field.at(i, j));
        }
        response->set_version(f->version());
        ToProto(EdgesOf(f->grid(), rect), response->mutable_window());
        response->set_width_px(rect.width());
        response->set_height_px(rect.height());
        return absl::OkStatus();
      },
      std::move(done));
}

void Service::PlanPath(CallPtr call, const v1::PlanPathRequest& request,
                       v1::PlanPathResponse* response, Done done) {
  Begun begun = Begin(*call, "PlanPath", Access::kRead, &request.scene_id());
  done = Ending(begun.scope, std::move(done));
  if (!begun.status.ok()) return done(begun.status);
  auto scene = PlaneOf(begun.scene);
  if (!scene.ok()) return done(scene.status());
  if (auto s = NeedsNearest((*scene)->settings(), "planning"); !s.ok()) return done(s);
  if (!request.has_start()) return done(Invalid("start is not set"));
  if (!request.has_goal()) return done(Invalid("goal is not set"));
  PlanRequest plan_request;
  plan_request.start = {request.start().x(), request.start().y()};
  plan_request.goal = {request.goal().x(), request.goal().y()};
  plan_request.radius = request.robot_radius();
  if (auto s = ToPathPreference(request, &plan_request.prefer); !s.ok()) return done(s);
  StartAnalysis(
      call, *scene, request.min_version(),
      [=](const std::shared_ptr<const Frame>& frame, const Scene& scene) {
        // Repeated plans on one frame share its clearance field.
        auto field = scene.Derived<ClearanceField>(frame, MakeClearanceField);
        auto plan = gvd::PlanPath(*frame, *field, plan_request);
        if (!plan.ok()) return plan.status();
        for (Vec2 p : plan->path) ToProto(p, response->add_path());
        response->set_min_clearance(plan->min_clearance);
        response->set_best_clearance(plan->best_clearance);
        response->set_length(plan->length);
        response->set_version(frame->version());
        return absl::OkStatus();
      },
      std::move(done));
}

void Service::RenderMosaic(CallPtr call, const v1::RenderMosaicRequest& request,
                           v1::RenderMosaicResponse* response, Done done) {
  Begun begun = Begin(*call, "RenderMosaic", Access::kRead);
  done = Ending(begun.scope, std::move(done));
  if (!begun.status.ok()) return done(begun.status);
  MosaicOptions options;
  std::string format;
  if (auto s = ToMosaicOptions(request, limits_, &options, &format); !s.ok()) return done(s);
  SceneRegistry* registry = registry_;
  const ServerLimits& limits = limits_;
  OnLane(
      registry_->analyses(), "--max-queued-analyses",
      [=, &request, &limits]() -> absl::Status {
        // The image's memory is reserved from its header, before its pixels are decoded.
        std::unique_ptr<MemoryBudget::Reservation> reserved;
        auto image = ReadImage(request.image(), "image", [&](const Image& header) -> absl::Status {
          if (auto s = MosaicImageFits(header, limits); !s.ok()) return s;
          auto r = registry->Reserve(
              MosaicBytes(header.width, header.height, header.channels),
              absl::StrCat("a mosaic of a ", header.width, "x", header.height, " image"));
          if (!r.ok()) return r.status();
          reserved = std::move(*r);
          return absl::OkStatus();
        });
        if (!image.ok()) return image.status();
        if (call->cancelled()) return absl::CancelledError("the call was cancelled");
        // The sites' diagram over the image's pixels, exact.
        const std::vector<Vec2> points = MosaicSites(*image, options);
        std::vector<Site> sites;
        sites.reserve(points.size());
        for (size_t k = 0; k < points.size(); ++k) {
          sites.push_back(Site{absl::StrCat(k), PointSite{points[k]}});
        }
        const Grid grid = ImageGrid(*image);
        auto rendered = registry->RenderSites(SiteSnapshot::Of(1, std::move(sites)), grid,
                                              grid.pixel_size(), RenderMode::kExact);
        if (!rendered.ok()) return rendered.status();
        const Frame& frame = **rendered;
        // Slots are the sites' indices: SiteSnapshot::Of fills them in order.
        std::vector<uint32_t> ids(grid.pixel_count());
        for (uint32_t j = 0; j < grid.height; ++j) {
          for (uint32_t i = 0; i < grid.width; ++i) ids[size_t{j} * grid.width + i] = frame.id_at(i, j);
        }
        auto mosaic = MakeMosaic(*image, points, ids, options);
        if (!mosaic.ok()) return mosaic.status();
        std::string file_format = format;
        if (file_format.empty()) {
          file_format = image->file_format == "gif" || image->file_format == "bmp"
                            ? "png"
                            : image->file_format;
        }
        auto bytes = WriteImage(*mosaic, file_format);
        if (!bytes.ok()) return bytes.status();
        response->set_image(std::move(*bytes));
        response->set_mime_type(MimeType(file_format));
        response->set_width_px(image->width);
        response->set_height_px(image->height);
        for (Vec2 p : points) ToProto(Vec2{p.x, image->height - p.y}, response->add_sites());
        return absl::OkStatus();
      },
      std::move(done));
}

}  // namespace gvd

// The service's calls on the structure of a diagram and its applications (paper sec. 5-7):
// boundaries, neighbours, Delaunay, zoom windows, clearance, planning and picking. Each waits
// for its frame like a query, then works on a worker thread (never on gRPC's), rendering
// zoom windows through the render thread when it needs them.
#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <unordered_map>

#include "absl/strings/str_cat.h"
#include "render/analysis/analysis.h"
#include "render/analysis/planning.h"
#include "render/analysis/refine.h"
#include "render/kernel/exact3.h"
#include "render/scene/cpu_pool.h"
#include "server/app/jobs.h"
#include "server/grpc/call_scope.h"
#include "server/grpc/convert.h"
#include "server/grpc/reactors.h"
#include "server/grpc/service.h"

namespace gvd {
namespace {

using grpc::Status;
using grpc::StatusCode;

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
              grpc::CallbackServerContext* ctx) {
  return [=](const std::vector<Grid>& grids)
             -> absl::StatusOr<std::vector<std::shared_ptr<const Frame>>> {
    if (ctx->IsCancelled()) return absl::CancelledError("the call was cancelled");
    return registry->Zoom(frame, mode, grids);
  };
}

// The frame's neighbour pairs in `rect`, refined through zoom windows unless `coarse`.
absl::StatusOr<RefinedNeighbors> Neighbours(SceneRegistry* registry,
                                            const std::shared_ptr<const Frame>& frame,
                                            PixelRect rect, bool coarse,
                                            grpc::CallbackServerContext* ctx) {
  ZoomFn zoom;
  if (!coarse) zoom = Zoomer(registry, frame, RenderMode::kExact, ctx);
  return RefineNeighbors(*frame, rect, zoom);
}

// The pixels of the frame a request names: its window (clipped), or all of them.
Status RectOf(bool has_window, const v1::Window& window, const Grid& grid, PixelRect* rect) {
  *rect = grid.all();
  return has_window ? ToPixelRect(window, grid, rect) : Status::OK;
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
Status ToZoomSpec(bool has_window, const v1::Window& window, uint32_t width, uint32_t height,
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
    return Status(StatusCode::RESOURCE_EXHAUSTED,
                  absl::StrCat(width, "x", height, " pixels do not fit in a message of ",
                               limits.max_message_bytes, " bytes (--max-message-bytes)"));
  }
  return Status::OK;
}

// The frame a ZoomSpec asks for, and the rect of it to answer with.
absl::StatusOr<std::pair<std::shared_ptr<const Frame>, PixelRect>> Resolve(
    const ZoomSpec& spec, const std::shared_ptr<const Frame>& frame, RenderMode mode,
    SceneRegistry* registry, grpc::CallbackServerContext* ctx) {
  if (!spec.render) return std::pair{frame, spec.rect};
  auto zoomed = Zoomer(registry, frame, mode, ctx)({spec.grid});
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

}  // namespace

grpc::ServerUnaryReactor* VoronoiService::StartAnalysis(const char* method,
                                                        grpc::CallbackServerContext* ctx,
                                                        const std::string& scene_id,
                                                        uint64_t min_version, Validate validate,
                                                        Work work) {
  Call call = Begin(ctx, method, Access::kRead, &scene_id);
  if (!call.ok()) return call.Finish(ctx);
  return StartAnalysis(call, ctx, min_version, std::move(validate), std::move(work));
}

grpc::ServerUnaryReactor* VoronoiService::StartAnalysis(const Call& call,
                                                        grpc::CallbackServerContext* ctx,
                                                        uint64_t min_version, Validate validate,
                                                        Work work) {
  if (validate) {
    if (auto s = validate(*call.scene); !s.ok()) return call.Finish(ctx, s);
  }
  auto version = registry_->ReadVersion(*call.scene, min_version);
  if (!version.ok()) return call.Finish(ctx, ToGrpc(version.status()));
  auto job = AnalysisJob::Make(
      registry_, call.scene, *version,
      [scene = call.scene, work = std::move(work)](const std::shared_ptr<const Frame>& frame) {
        return work(frame, *scene);
      },
      [ctx] { return ctx->IsCancelled(); });
  return JobReactor<AnalysisJob>::Start(call.scope, job, nullptr);
}

grpc::ServerUnaryReactor* VoronoiService::GetBoundaries(grpc::CallbackServerContext* ctx,
                                                        const v1::GetBoundariesRequest* request,
                                                        v1::GetBoundariesResponse* response) {
  struct Params {
    PixelRect rect;
    BoundaryMethod method = BoundaryMethod::kFullScan;
  };
  auto p = std::make_shared<Params>();
  return StartAnalysis(
      "GetBoundaries", ctx, request->scene_id(), request->min_version(),
      [=](const Scene& scene) {
        if (auto s = ToBoundaryMethod(*request, &p->method); !s.ok()) return s;
        return RectOf(request->has_window(), request->window(), scene.settings().grid,
                      &p->rect);
      },
      [=](const std::shared_ptr<const Frame>& frame, const Scene&) {
        IdImage image = IdsOf(*frame, p->rect);
        BoundaryEdges edges = FindBoundaryEdges(image, p->method);
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
      });
}

grpc::ServerUnaryReactor* VoronoiService::GetNeighbors(grpc::CallbackServerContext* ctx,
                                                       const v1::GetNeighborsRequest* request,
                                                       v1::GetNeighborsResponse* response) {
  auto rect = std::make_shared<PixelRect>();
  SceneRegistry* registry = registry_;
  return StartAnalysis(
      "GetNeighbors", ctx, request->scene_id(), request->min_version(),
      [=](const Scene& scene) {
        return RectOf(request->has_window(), request->window(), scene.settings().grid,
                      rect.get());
      },
      [=](const std::shared_ptr<const Frame>& frame, const Scene&) {
        const std::string& only = request->site_id();
        if (!only.empty()) {
          bool live = false;
          for (uint32_t s = 0; s < frame->sites().size() && !live; ++s) {
            const Site* site = frame->sites().get(s);
            live = site && site->id == only;
          }
          if (!live) {
            return absl::NotFoundError(
                          absl::StrCat("site_id \"", only, "\" is not in the scene at version ",
                                       frame->version()));
          }
        }
        auto r = Neighbours(registry, frame, *rect, request->coarse(), ctx);
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
      });
}

grpc::ServerUnaryReactor* VoronoiService::GetDelaunay(grpc::CallbackServerContext* ctx,
                                                      const v1::GetDelaunayRequest* request,
                                                      v1::GetDelaunayResponse* response) {
  SceneRegistry* registry = registry_;
  return StartAnalysis(
      "GetDelaunay", ctx, request->scene_id(), request->min_version(), nullptr,
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
        auto r = Neighbours(registry, frame, frame->grid().all(), request->coarse(), ctx);
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
      });
}

grpc::ServerUnaryReactor* VoronoiService::RenderWindow(grpc::CallbackServerContext* ctx,
                                                       const v1::RenderWindowRequest* request,
                                                       v1::RenderWindowResponse* response) {
  auto spec = std::make_shared<ZoomSpec>();
  SceneRegistry* registry = registry_;
  const ServerLimits limits = limits_;
  return StartAnalysis(
      "RenderWindow", ctx, request->scene_id(), request->min_version(),
      [=](const Scene& scene) {
        return ToZoomSpec(request->has_window(), request->window(), request->width_px(),
                          request->height_px(), scene.settings().grid, limits, spec.get());
      },
      [=](const std::shared_ptr<const Frame>& frame, const Scene& scene) {
        auto resolved = Resolve(*spec, frame, scene.settings().mode, registry, ctx);
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
      });
}

grpc::ServerUnaryReactor* VoronoiService::RenderImageAt(const Call& call,
                                                        grpc::CallbackServerContext* ctx,
                                                        const v1::RenderImageRequest* request,
                                                        v1::RenderImageResponse* response) {
  auto spec = std::make_shared<ZoomSpec>();
  auto options = std::make_shared<ImageOptions>();
  SceneRegistry* registry = registry_;
  const ServerLimits limits = limits_;
  return StartAnalysis(
      call, ctx, request->min_version(),
      [=](const Scene& scene) {
        if (auto s = ToZoomSpec(request->has_window(), request->window(), request->width_px(),
                                request->height_px(), scene.settings().grid, limits, spec.get(),
                                /*pixel_bytes=*/0);
            !s.ok()) {
          return s;
        }
        // The request's window is the zoom grid's: all of its pixels.
        return ToImageOptions(*request, spec->grid, options.get());
      },
      [=](const std::shared_ptr<const Frame>& frame, const Scene& scene) {
        auto resolved = Resolve(*spec, frame, scene.settings().mode, registry, ctx);
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
        if (const size_t bytes = response->ByteSizeLong(); bytes > size_t(limits.max_message_bytes)) {
          response->Clear();
          return absl::ResourceExhaustedError(absl::StrCat(
              "the ", options->rect.width(), "x", options->rect.height(), " image's answer is ",
              bytes, " bytes, more than a message holds (--max-message-bytes ",
              limits.max_message_bytes, ")"));
        }
        return absl::OkStatus();
      });
}

grpc::ServerUnaryReactor* VoronoiService::GetClearanceField(
    grpc::CallbackServerContext* ctx, const v1::GetClearanceFieldRequest* request,
    v1::GetClearanceFieldResponse* response) {
  Call call = Begin(ctx, "GetClearanceField", Access::kRead, &request->scene_id(),
                    /*three_d=*/true);
  if (!call.ok()) return call.Finish(ctx);
  if (call.scene3) return ClearanceField3(call, ctx, request, response);
  if (request->depth_px() != 0 || request->gradients() || request->site_indices() ||
      request->window().min_z() != 0 || request->window().max_z() != 0) {
    return call.Finish(ctx, Status(StatusCode::INVALID_ARGUMENT,
                                   "depth_px, window.min_z/max_z, gradients and site_indices "
                                   "are for 3D scenes; scene \"" + request->scene_id() +
                                       "\" is 2D"));
  }
  auto spec = std::make_shared<ZoomSpec>();
  SceneRegistry* registry = registry_;
  const ServerLimits limits = limits_;
  return StartAnalysis(
      call, ctx, request->min_version(),
      [=](const Scene& scene) {
        if (scene.settings().diagram != Diagram::kNearest) {
          return Status(StatusCode::FAILED_PRECONDITION,
                        absl::StrCat("scene \"", scene.id(),
                                     "\" is a FARTHEST diagram; clearance needs NEAREST"));
        }
        return ToZoomSpec(request->has_window(), request->window(), request->width_px(),
                          request->height_px(), scene.settings().grid, limits, spec.get());
      },
      [=](const std::shared_ptr<const Frame>& frame, const Scene& scene) {
        auto resolved = Resolve(*spec, frame, scene.settings().mode, registry, ctx);
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
      });
}

grpc::ServerUnaryReactor* VoronoiService::ClearanceField3(
    const Call& call, grpc::CallbackServerContext* ctx, const v1::GetClearanceFieldRequest* request,
    v1::GetClearanceFieldResponse* response) {
  const Scene3& scene = *call.scene3;
  if (scene.settings().diagram != Diagram::kNearest) {
    return call.Finish(ctx, Status(StatusCode::FAILED_PRECONDITION,
                                   absl::StrCat("scene \"", scene.id(),
                                                "\" is a FARTHEST diagram; clearance needs NEAREST")));
  }
  auto samples = std::make_shared<ClearanceSamples3>();
  if (auto s = ToClearanceSamples3(*request, scene.settings().grid3(), scene.site_count(), limits_,
                                   samples.get());
      !s.ok()) {
    return call.Finish(ctx, s);
  }
  auto version = registry_->ReadVersion(scene, request->min_version());
  if (!version.ok()) return call.Finish(ctx, ToGrpc(version.status()));
  const bool gradients = request->gradients(), indices = request->site_indices();
  // Written straight into the response, on the analyses lane and the CPU pool: the scene's
  // voxels as they are (a stored value less its rounding slack bounds the distance from
  // below, the render being exact per voxel), or each sample's answer from the volume less
  // its bound (exact outside the box). A gradient points from the sample's site's nearest
  // point.
  auto work = [=](const std::shared_ptr<const Volume>& volume) -> absl::Status {
    const ClearanceSamples3& at = *samples;
    const int n = static_cast<int>(at.count());
    auto* clearance = response->mutable_clearance();
    clearance->Resize(n, INFINITY);
    float* gradient = nullptr;
    uint32_t* ids = nullptr;
    if (gradients) {
      response->mutable_gradient()->Resize(3 * n, 0);
      gradient = response->mutable_gradient()->mutable_data();
    }
    if (indices) {
      response->mutable_ids()->Resize(n, 0);
      ids = response->mutable_ids()->mutable_data();
    }
    float* out = clearance->mutable_data();
    std::vector<uint32_t> slots(indices ? n : 0, 0);  // slot + 1 per sample, 0 none
    const ErrorModel& error = volume->error();
    const uint32_t rows = at.height * at.depth;
    ParallelFor(rows, 4, [&](size_t begin, size_t end) {
      for (size_t row = begin; row < end; ++row) {
        const uint32_t j = static_cast<uint32_t>(row % at.height);
        const uint32_t k = static_cast<uint32_t>(row / at.height);
        for (uint32_t i = 0; i < at.width; ++i) {
          const size_t s = row * at.width + i;
          const Vec3 q = at.At(i, j, k);
          uint32_t slot = 0;  // + 1
          double lower = INFINITY;
          if (at.own) {
            slot = volume->id_at(at.first[0] + i, at.first[1] + j, at.first[2] + k);
            if (slot != 0) {
              lower = error.LowerBound(volume->distance_at(at.first[0] + i, at.first[1] + j,
                                                           at.first[2] + k));
            }
          } else if (auto answer = volume->Nearest(q); answer && answer->found) {
            slot = answer->site_index + 1;
            lower = answer->distance - answer->error_bound;
          }
          if (slot == 0) continue;
          // A lower bound in float: rounded down from the double one.
          lower = std::max(0.0, lower);
          float f = static_cast<float>(lower);
          if (double{f} > lower) f = std::nextafter(f, -INFINITY);
          out[s] = f;
          if (gradient != nullptr) {
            const Vec3 closest = NearestFeature(q, volume->sites().get(slot - 1)->geometry).closest;
            const Vec3 g = UnitGradient(q, closest);
            for (int a = 0; a < 3; ++a) gradient[3 * s + a] = static_cast<float>(g[a]);
          }
          if (indices) slots[s] = slot;
        }
      }
    });
    if (indices) {  // 1 + an index into site_ids, in the order the samples first name them
      std::unordered_map<uint32_t, uint32_t> named;
      for (int s = 0; s < n; ++s) {
        if (slots[s] == 0) continue;
        auto [it, fresh] = named.try_emplace(slots[s], static_cast<uint32_t>(named.size() + 1));
        if (fresh) response->add_site_ids(volume->sites().get(slots[s] - 1)->id);
        ids[s] = it->second;
      }
    }
    response->set_version(volume->version());
    v1::Window* w = response->mutable_window();
    w->set_min_x(at.box.min_x);
    w->set_min_y(at.box.min_y);
    w->set_min_z(at.box.min_z);
    w->set_max_x(at.box.max_x);
    w->set_max_y(at.box.max_y);
    w->set_max_z(at.box.max_z);
    response->set_width_px(at.width);
    response->set_height_px(at.height);
    response->set_depth_px(at.depth);
    return absl::OkStatus();
  };
  auto job = AnalysisJob3::Make(registry_, call.scene3, *version, std::move(work),
                                [ctx] { return ctx->IsCancelled(); });
  return JobReactor<AnalysisJob3>::Start(call.scope, job, nullptr);
}

grpc::ServerUnaryReactor* VoronoiService::PlanPath(grpc::CallbackServerContext* ctx,
                                                   const v1::PlanPathRequest* request,
                                                   v1::PlanPathResponse* response) {
  auto plan_request = std::make_shared<PlanRequest>();
  return StartAnalysis(
      "PlanPath", ctx, request->scene_id(), request->min_version(),
      [=](const Scene& scene) {
        if (scene.settings().diagram != Diagram::kNearest) {
          return Status(StatusCode::FAILED_PRECONDITION,
                        absl::StrCat("scene \"", scene.id(),
                                     "\" is a FARTHEST diagram; planning needs NEAREST"));
        }
        if (!request->has_start()) return Status(StatusCode::INVALID_ARGUMENT, "start is not set");
        if (!request->has_goal()) return Status(StatusCode::INVALID_ARGUMENT, "goal is not set");
        plan_request->start = {request->start().x(), request->start().y()};
        plan_request->goal = {request->goal().x(), request->goal().y()};
        plan_request->radius = request->robot_radius();
        return ToPathPreference(*request, &plan_request->prefer);
      },
      [=](const std::shared_ptr<const Frame>& frame, const Scene& scene) {
        // Repeated plans on one frame share its clearance field.
        auto field = scene.Derived<ClearanceField>(frame, MakeClearanceField);
        auto plan = gvd::PlanPath(*frame, *field, *plan_request);
        if (!plan.ok()) return plan.status();
        for (Vec2 p : plan->path) {
          v1::Point* out = response->add_path();
          out->set_x(p.x);
          out->set_y(p.y);
        }
        response->set_min_clearance(plan->min_clearance);
        response->set_best_clearance(plan->best_clearance);
        response->set_length(plan->length);
        response->set_version(frame->version());
        return absl::OkStatus();
      });
}

grpc::ServerUnaryReactor* VoronoiService::Pick(grpc::CallbackServerContext* ctx,
                                               const v1::PickRequest* request,
                                               v1::PickResponse* response) {
  Call call = Begin(ctx, "Pick", Access::kRead, &request->scene_id(), /*three_d=*/true);
  if (!call.ok()) return call.Finish(ctx);
  auto respond = [response](const auto& picked, auto point) {
    response->set_found(picked.found);
    response->set_version(picked.version);
    if (picked.found) {
      response->set_site_id(picked.site->id);
      response->set_distance(picked.distance);
      response->set_feature_kind(ToProto(picked.feature_kind));
      response->set_feature_index(picked.feature_index);
      ToProto(picked.closest, response->mutable_closest());
      ToProto(UnitGradient(point, picked.closest), response->mutable_gradient());
      ToProto(*picked.site, response->mutable_site());
    }
  };
  if (call.scene3) {
    Vec3 point;
    double max_distance;
    if (auto s = ToPick3(*request, &point, &max_distance); !s.ok()) return call.Finish(ctx, s);
    respond(call.scene3->Pick(point, max_distance), point);
    return call.Finish(ctx, Status::OK);
  }
  Vec2 point;
  double max_distance;
  if (auto s = ToPick(*request, &point, &max_distance); !s.ok()) return call.Finish(ctx, s);
  respond(call.scene->Pick(point, max_distance), point);
  return call.Finish(ctx, Status::OK);
}

}  // namespace gvd

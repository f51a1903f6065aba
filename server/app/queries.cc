// The service's queries of points and images: FindNearest (whole answers, or packed columns),
// its stream of packed chunks, RenderImage and Pick.
#include "server/app/convert/queries.h"

#include <algorithm>
#include <unordered_map>

#include "absl/strings/str_cat.h"
#include "server/app/convert/common.h"
#include "server/app/convert/images.h"
#include "server/app/convert/sites.h"
#include "server/app/jobs.h"
#include "server/app/service.h"

namespace gvd {
namespace {

// The packed columns a FindNearest request asks for: bit f for v1::NearestField f.
constexpr uint32_t kDefaultFields = 0x3e;  // SITE .. FEATURE, when a request names none
constexpr uint32_t Bit(v1::NearestField f) { return 1u << f; }
// The fields that a request with `points` may name: they add to whole NearestSite messages.
constexpr uint32_t kPointFields =
    Bit(v1::NEAREST_FIELD_CLOSEST) | Bit(v1::NEAREST_FIELD_GRADIENT);

// Writes the job's answers [begin, end): as NearestSite results into `response`, or packed
// into `p` (only the columns in `fields`: bit f for v1::NearestField f), one of the two.
// A template on the job: closest points and gradients have 2 or 3 coordinates.
template <class J>
void Fill(const J& job, size_t begin, size_t end, uint32_t fields,
          v1::FindNearestResponse* response, v1::PackedNearest* p) {
  using Point = typename J::Point;
  constexpr int kWidth = Point::length();
  const std::vector<AnswerRow>& rows = job.rows();
  const std::vector<Point>& points = job.points();
  const std::vector<Point>& nearest_points = job.closest();  // filled when asked for
  const bool closest = (fields & Bit(v1::NEAREST_FIELD_CLOSEST)) != 0;
  const bool gradient = (fields & Bit(v1::NEAREST_FIELD_GRADIENT)) != 0;
  if (p == nullptr) {
    auto* results = response->mutable_results();
    results->Reserve(static_cast<int>(end - begin));
    for (size_t i = begin; i < end; ++i) {
      v1::NearestSite* r = results->Add();
      if (rows[i].site_id == nullptr) {
        r->set_empty(true);
        r->set_distance(INFINITY);
        r->set_exact(true);
        continue;
      }
      r->set_site_id(*rows[i].site_id);
      r->set_distance(rows[i].distance);
      r->set_error_bound(rows[i].error_bound);
      r->set_exact(rows[i].exact);
      r->set_feature_index(rows[i].feature_index);
      r->set_feature_kind(ToProto(rows[i].feature_kind));
      if (closest) ToProto(nearest_points[i], r->mutable_closest());
      if (gradient) ToProto(UnitGradient(points[i], nearest_points[i]), r->mutable_gradient());
    }
    return;
  }
  // Each column asked for is sized once and written in place; a site's index in site_ids is
  // looked up by its slot (all rows come from one version).
  const int n = static_cast<int>(end - begin);
  auto wants = [fields](v1::NearestField f) { return (fields & (1u << f)) != 0; };
  // A column of `width` values an answer (x and y: 2), sized once, or null when not wanted.
  auto column = [n](auto* field, bool wanted, int width = 1) {
    if (!wanted) return decltype(field->mutable_data())(nullptr);
    field->Resize(width * n, {});
    return field->mutable_data();
  };
  uint32_t* site = column(p->mutable_site(), wants(v1::NEAREST_FIELD_SITE));
  double* distance = column(p->mutable_distance(), wants(v1::NEAREST_FIELD_DISTANCE));
  double* error_bound =
      column(p->mutable_error_bound(), wants(v1::NEAREST_FIELD_ERROR_BOUND));
  bool* exact = column(p->mutable_exact(), wants(v1::NEAREST_FIELD_EXACT));
  uint32_t* feature_index =
      column(p->mutable_feature_index(), wants(v1::NEAREST_FIELD_FEATURE));
  int* feature_kind = column(p->mutable_feature_kind(), wants(v1::NEAREST_FIELD_FEATURE));
  double* closest_xy = column(p->mutable_closest(), closest, kWidth);
  double* gradient_xy = column(p->mutable_gradient(), gradient, kWidth);
  if (site != nullptr) {
    // slot -> 1 + index in site_ids (0 for none): a table over the slots when the rows are
    // many for the slots they span (a large batch), a hash map otherwise (small stream chunks
    // of a large scene).
    uint32_t slots = 0;
    for (size_t i = begin; i < end; ++i) slots = std::max(slots, rows[i].slot + 1);
    const bool dense = slots <= 4 * size_t(n) + 1024;
    std::vector<uint32_t> table(dense ? slots : 0, 0);
    std::unordered_map<uint32_t, uint32_t> map;
    for (size_t i = begin, k = 0; i < end; ++i, ++k) {
      const AnswerRow& row = rows[i];
      if (row.site_id == nullptr) {
        site[k] = 0;
        continue;
      }
      uint32_t& name = dense ? table[row.slot] : map.try_emplace(row.slot, 0).first->second;
      if (name == 0) {
        p->add_site_ids(*row.site_id);
        name = static_cast<uint32_t>(p->site_ids_size());
      }
      site[k] = name;
    }
  }
  for (size_t i = begin, k = 0; i < end; ++i, ++k) {
    const AnswerRow& row = rows[i];
    if (distance) distance[k] = row.distance;
    if (error_bound) error_bound[k] = row.error_bound;
    if (exact) exact[k] = row.exact;
    if (feature_index) {
      feature_index[k] = row.feature_index;
      feature_kind[k] = ToProto(row.feature_kind);
    }
    if (closest_xy || gradient_xy) {
      const Point c = nearest_points[i];  // NaN for an empty answer
      const Point g = row.site_id == nullptr ? Point(NAN) : UnitGradient(points[i], c);
      for (int a = 0; a < kWidth; ++a) {
        if (closest_xy) closest_xy[kWidth * k + a] = c[a];
        if (gradient_xy) gradient_xy[kWidth * k + a] = g[a];
      }
    }
  }
}

// Validates a FindNearest or FindNearestStream request on its scene and resolves its points
// and mode, and the packed columns it asks for (bit f for v1::NearestField f). `packed`:
// whether the answers go out packed (a request with packed points, and every stream).
template <class S, class Request>
absl::Status ParseNearest(const SceneRegistry& registry, const Request& request,
                          const S& scene, bool packed, BasicNearestQuery<typename S::Point>* query,
                          uint32_t* fields) {
  bool outside = false;
  const auto& bounds = SceneFrames<typename S::Kernel>::Bounds(scene.settings());
  if (auto s = ToQueryPoints(request, bounds, registry.limits(), &query->points, &outside);
      !s.ok()) {
    return s;
  }
  auto version = registry.ReadVersion(scene, request.min_version());
  if (!version.ok()) return version.status();
  query->min_version = *version;
  query->exact = request.exact() || outside;
  query->skip_refinement = request.skip_refinement();
  *fields = packed ? kDefaultFields : 0;
  if (request.fields_size() > 0) {
    *fields = 0;
    for (int i = 0; i < request.fields_size(); ++i) {
      const int f = request.fields(i);
      if (f < v1::NEAREST_FIELD_SITE || f > v1::NEAREST_FIELD_GRADIENT) {
        return Invalid(absl::StrCat("fields[", i, "] is ", f,
                                    "; it must be NEAREST_FIELD_SITE to NEAREST_FIELD_GRADIENT"));
      }
      if (!packed && (Bit(static_cast<v1::NearestField>(f)) & kPointFields) == 0) {
        return Invalid(absl::StrCat("fields[", i, "] is ", v1::NearestField_Name(f),
                                    "; with points, whose answers are whole NearestSite "
                                    "messages, fields may name only NEAREST_FIELD_CLOSEST and "
                                    "NEAREST_FIELD_GRADIENT (send the points as xy, or xyz, to "
                                    "choose the columns of packed answers)"));
      }
      *fields |= 1u << f;
    }
  }
  query->features = !packed || (*fields & Bit(v1::NEAREST_FIELD_FEATURE)) != 0;
  query->closest =
      (*fields & (Bit(v1::NEAREST_FIELD_CLOSEST) | Bit(v1::NEAREST_FIELD_GRADIENT))) !=
      0;
  return absl::OkStatus();
}

// The query's job, cancelled with its call.
template <class Job>
void Watch(const CallPtr& call, const std::shared_ptr<Job>& job) {
  call->OnCancel([weak = std::weak_ptr<Job>(job)] {
    if (auto job = weak.lock()) job->Cancel();
  });
}

// Runs the job, then `respond` (on OK), then `done` with the job's status.
template <class Job>
void Run(const CallPtr& call, std::shared_ptr<Job> job, std::function<void(const Job&)> respond,
         Done done) {
  Watch(call, job);
  Job* raw = job.get();  // the job keeps itself alive until it calls back
  raw->Start([raw, respond = std::move(respond), done = std::move(done)](const absl::Status& s) {
    if (s.ok() && respond) respond(*raw);
    done(s);
  });
}

// FindNearestStream's writer: the job's answers in chunks, one write at a time.
template <class J>
class NearestChunks : public std::enable_shared_from_this<NearestChunks<J>> {
 public:
  NearestChunks(std::shared_ptr<CallScope> scope, std::shared_ptr<J> job, uint32_t fields,
                size_t chunk, StreamWriter<v1::FindNearestStreamResponse>* out)
      : scope_(std::move(scope)), job_(std::move(job)), fields_(fields), chunk_(chunk), out_(out) {}

  void Start(const CallPtr& call) {
    Watch(call, job_);
    auto self = this->shared_from_this();
    job_->Start([self](const absl::Status& s) {
      if (!s.ok()) return self->End(s);
      self->Next();
    });
  }

 private:
  void Next() {
    const auto& rows = job_->rows();
    if (offset_ >= rows.size()) return End(absl::OkStatus());
    const size_t end = std::min(rows.size(), offset_ + chunk_);
    message_.Clear();
    message_.set_version(job_->version());
    message_.set_offset(offset_);
    Fill(*job_, offset_, end, fields_, nullptr, message_.mutable_packed());
    offset_ = end;
    auto self = this->shared_from_this();
    out_->Write(&message_, [self](bool ok) {
      if (!ok) return self->End(absl::CancelledError("the client stopped reading"));
      self->Next();
    });
  }
  void End(const absl::Status& s) {
    scope_->Record(s);
    out_->Finish(s);
  }

  const std::shared_ptr<CallScope> scope_;
  const std::shared_ptr<J> job_;
  const uint32_t fields_;
  const size_t chunk_;
  StreamWriter<v1::FindNearestStreamResponse>* const out_;
  size_t offset_ = 0;
  v1::FindNearestStreamResponse message_;
};

}  // namespace

void Service::FindNearest(CallPtr call, const v1::FindNearestRequest& request,
                          v1::FindNearestResponse* response, Done done) {
  Begun begun = Begin(*call, "FindNearest", Access::kRead, &request.scene_id());
  done = Ending(begun.scope, std::move(done));
  if (!begun.status.ok()) return done(begun.status);
  begun.scene->Visit([&](const auto& scene) {
    using Job = BasicNearestJob<std::decay_t<decltype(*scene)>>;
    typename Job::Query query;
    uint32_t fields = 0;
    const bool packed = request.points_size() == 0;
    if (auto s = ParseNearest(*registry_, request, *scene, packed, &query, &fields); !s.ok()) {
      return done(s);
    }
    auto job = Job::Make(registry_, scene, std::move(query), [call] { return call->cancelled(); });
    Run<Job>(
        call, job,
        [=](const Job& job) {
          response->set_version(job.version());
          Fill(job, 0, job.rows().size(), fields, response,
               packed ? response->mutable_packed() : nullptr);
        },
        std::move(done));
  });
}

void Service::FindNearestStream(CallPtr call, const v1::FindNearestStreamRequest& request,
                                StreamWriter<v1::FindNearestStreamResponse>* stream) {
  Begun begun = Begin(*call, "FindNearestStream", Access::kRead, &request.scene_id());
  auto refuse = [&](const absl::Status& s) {
    begun.scope->Record(s);
    stream->Finish(s);
  };
  if (!begun.status.ok()) return refuse(begun.status);
  begun.scene->Visit([&](const auto& scene) {
    using Job = BasicNearestJob<std::decay_t<decltype(*scene)>>;
    typename Job::Query query;
    uint32_t fields = 0;
    if (auto s = ParseNearest(*registry_, request, *scene, /*packed=*/true, &query, &fields);
        !s.ok()) {
      return refuse(s);
    }
    const size_t chunk = request.chunk_size() == 0 ? 65536 : request.chunk_size();
    auto job = Job::Make(registry_, scene, std::move(query), [call] { return call->cancelled(); });
    std::make_shared<NearestChunks<Job>>(begun.scope, job, fields, chunk, stream)->Start(call);
  });
}

void Service::RenderImage(CallPtr call, const v1::RenderImageRequest& request,
                          v1::RenderImageResponse* response, Done done) {
  Begun begun = Begin(*call, "RenderImage", Access::kRead, &request.scene_id());
  done = Ending(begun.scope, std::move(done));
  if (!begun.status.ok()) return done(begun.status);
  begun.scene->Visit([&](const auto& scene) {
    using S = std::decay_t<decltype(*scene)>;
    ImageOptions options;
    if constexpr (S::Kernel::kDimension == 2) {
      if (request.width_px() != 0 || request.height_px() != 0) {
        return RenderImageAt(call, scene, request, response, std::move(done));
      }
    }
    const auto& grid = SceneFrames<typename S::Kernel>::GridOf(scene->settings());
    if (auto s = ToImageOptions(request, grid, &options); !s.ok()) return done(s);
    if constexpr (S::Kernel::kDimension == 3) {
      response->set_slice(options.slice);
      response->set_slice_z(grid.SliceZ(options.slice));
    }
    auto version = registry_->ReadVersion(*scene, request.min_version());
    if (!version.ok()) return done(version.status());
    using Job = BasicImageJob<S>;
    auto job = Job::Make(registry_, scene, *version, std::move(options),
                         [call] { return call->cancelled(); });
    Run<Job>(
        call, job,
        [response](const Job& job) {
          const EncodedImage& image = job.image();
          response->set_image(image.bytes.data(), image.bytes.size());
          response->set_mime_type(image.mime_type);
          response->set_width_px(image.width);
          response->set_height_px(image.height);
          response->set_version(job.version());
          for (const std::string& id : image.site_ids) response->add_site_ids(id);
          ToProto(job.window(), response->mutable_window());
        },
        std::move(done));
  });
}

void Service::Pick(CallPtr call, const v1::PickRequest& request, v1::PickResponse* response,
                   Done done) {
  Begun begun = Begin(*call, "Pick", Access::kRead, &request.scene_id());
  done = Ending(begun.scope, std::move(done));
  if (!begun.status.ok()) return done(begun.status);
  begun.scene->Visit([&](const auto& scene) {
    typename std::decay_t<decltype(*scene)>::Point point;
    double max_distance = 0;
    if (auto s = ToPick(request, &point, &max_distance); !s.ok()) return done(s);
    const auto picked = scene->Pick(point, max_distance);
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
    done(absl::OkStatus());
  });
}

}  // namespace gvd

// The gvd commands on a diagram's structure and its applications: boundaries, neighbors,
// delaunay, zoom, clearance, plan, pick and mosaic.
#include "client/cli/cli.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <sstream>

#include "absl/status/status.h"
#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "client/cli/field_image.h"

namespace gvd::cli {
namespace {

bool EndsWith(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

int WriteFailed(const absl::Status& s) {
  std::fprintf(stderr, "gvd: %s\n", std::string(s.message()).c_str());
  return 1;
}

// "-" for no site.
const std::string& Name(const std::string& id) {
  static const std::string kNone = "-";
  return id.empty() ? kNone : id;
}

}  // namespace

int Boundaries(const Args& a, Client& client) {
  v1::GetBoundariesRequest r;
  r.set_scene_id(a.scene);
  if (const std::string* window = Option(a, "--window")) ParseWindow(*window, r.mutable_window());
  if (const std::string* m = Option(a, "--method")) {
    if (*m == "full") r.set_method(v1::GetBoundariesRequest::METHOD_FULL_SCAN);
    else if (*m == "continuation") r.set_method(v1::GetBoundariesRequest::METHOD_CONTINUATION);
    else Usage("--method must be full or continuation");
  }
  r.set_min_version(MinVersion(a));
  v1::GetBoundariesResponse response;
  if (auto s = client.GetBoundaries(r, &response); !s.ok()) return Fail(s);
  if (a.json) {
    PrintJson(response);
    return 0;
  }
  for (const auto& b : response.boundaries()) {
    std::cout << Name(b.site_a()) << " " << b.site_b();
    for (int k = 0; k + 1 < b.xy_size(); k += 2) std::cout << " " << Num(b.xy(k)) << "," << Num(b.xy(k + 1));
    if (b.closed()) std::cout << " closed";
    std::cout << "\n";
  }
  std::cerr << response.boundaries_size() << " boundaries, " << response.boundary_pixel_pairs()
            << " pixel pairs, " << response.cells_visited() << " cells visited, version "
            << response.version() << "\n";
  return 0;
}

namespace {

void PrintHidden(const google::protobuf::RepeatedPtrField<v1::HiddenSite>& hidden) {
  for (const auto& h : hidden) {
    std::cerr << "hidden: " << h.site_id() << " holds no pixel; "
              << (h.recovered() ? "found by zooming" : "no region found") << "\n";
  }
}

}  // namespace

int Neighbors(const Args& a, Client& client) {
  const auto& w = a.words;
  if (w.size() > 2) Usage("usage: gvd neighbors [SITE] [--window W] [--coarse]");
  v1::GetNeighborsRequest r;
  r.set_scene_id(a.scene);
  if (w.size() == 2) r.set_site_id(w[1]);
  if (const std::string* window = Option(a, "--window")) ParseWindow(*window, r.mutable_window());
  r.set_coarse(Option(a, "--coarse") != nullptr);
  r.set_min_version(MinVersion(a));
  v1::GetNeighborsResponse response;
  if (auto s = client.GetNeighbors(r, &response); !s.ok()) return Fail(s);
  if (a.json) {
    PrintJson(response);
    return 0;
  }
  for (const auto& p : response.pairs()) std::cout << p.site_a() << " " << p.site_b() << "\n";
  PrintHidden(response.hidden());
  std::cerr << response.pairs_size() << " pairs, " << response.zoom_windows()
            << " zoom windows to depth " << response.zoom_depth() << ", version "
            << response.version() << "\n";
  return 0;
}

int Delaunay(const Args& a, Client& client) {
  if (a.words.size() != 1) Usage("usage: gvd delaunay [--coarse]");
  v1::GetDelaunayRequest r;
  r.set_scene_id(a.scene);
  r.set_coarse(Option(a, "--coarse") != nullptr);
  r.set_min_version(MinVersion(a));
  v1::GetDelaunayResponse response;
  if (auto s = client.GetDelaunay(r, &response); !s.ok()) return Fail(s);
  if (a.json) {
    PrintJson(response);
    return 0;
  }
  for (const auto& t : response.triangles()) std::cout << t.a() << " " << t.b() << " " << t.c() << "\n";
  PrintHidden(response.hidden());
  std::cerr << response.triangles_size() << " triangles, " << response.edges_size() << " edges, "
            << response.zoom_windows() << " zoom windows, version " << response.version() << "\n";
  return 0;
}

int Zoom(const Args& a, Client& client) {
  const std::string* out = Option(a, "--output");
  const std::string* window = Option(a, "--window");
  const std::string* size = Option(a, "--size");
  if (!out || !window || !size) Usage("usage: gvd zoom -o OUT --window W --size WIDTHxHEIGHT");
  std::string layer = Option(a, "--layer") ? *Option(a, "--layer") : "ids";
  if (layer != "ids" && layer != "distance") Usage("--layer must be ids or distance");
  // The window at its size: an image (ids) and a raster (distances) ask alike.
  auto ask = [&](auto& r) {
    r.set_scene_id(a.scene);
    ParseWindow(*window, r.mutable_window());
    uint32_t width, height;
    ParseSize(*size, &width, &height);
    r.set_width_px(width);
    r.set_height_px(height);
    r.set_min_version(MinVersion(a));
  };
  if (layer == "ids") {
    // The server colours the sites, as in every image of it.
    if (!EndsWith(*out, ".png")) Usage("--layer ids writes a PNG: name OUT .png");
    v1::RenderImageRequest r;
    ask(r);
    v1::RenderImageResponse response;
    if (auto s = client.RenderImage(r, &response); !s.ok()) return Fail(s);
    if (int e = WriteBytes(*out, response.image())) return e;
    std::cout << "wrote " << *out << ": " << response.width_px() << "x" << response.height_px()
              << " ids, version " << response.version() << "\n";
    return 0;
  }
  v1::RenderWindowRequest r;
  ask(r);
  v1::RenderWindowResponse response;
  if (auto s = client.RenderWindow(r, &response); !s.ok()) return Fail(s);
  if (auto s = WriteField(*out, response.width_px(), response.height_px(), response.distances().data());
      !s.ok()) {
    return WriteFailed(s);
  }
  std::cout << "wrote " << *out << ": " << response.width_px() << "x" << response.height_px()
            << " distance, " << response.site_ids_size() << " sites, max_error "
            << Num(response.max_error()) << ", version " << response.version() << "\n";
  return 0;
}

int Clearance(const Args& a, Client& client) {
  const std::string* out = Option(a, "--output");
  if (!out) Usage("usage: gvd clearance -o OUT [--window W --size WxH]");
  v1::GetClearanceFieldRequest r;
  r.set_scene_id(a.scene);
  if (const std::string* window = Option(a, "--window")) ParseWindow(*window, r.mutable_window());
  if (const std::string* size = Option(a, "--size")) {
    uint32_t width, height;
    ParseSize(*size, &width, &height);
    r.set_width_px(width);
    r.set_height_px(height);
  }
  r.set_min_version(MinVersion(a));
  v1::GetClearanceFieldResponse response;
  if (auto s = client.GetClearanceField(r, &response); !s.ok()) return Fail(s);
  if (auto s = WriteField(*out, response.width_px(), response.height_px(), response.clearance().data());
      !s.ok()) {
    return WriteFailed(s);
  }
  std::cout << "wrote " << *out << ": " << response.width_px() << "x" << response.height_px()
            << " clearance, version " << response.version() << "\n";
  return 0;
}

int Plan(const Args& a, Client& client) {
  const std::string* from = Option(a, "--from");
  const std::string* to = Option(a, "--to");
  if (!from || !to || a.words.size() != 1) {
    Usage("usage: gvd plan --from X,Y --to X,Y [--radius R] [--prefer clearance|shortest] [-o OUT.png]");
  }
  v1::PlanPathRequest r;
  r.set_scene_id(a.scene);
  ParsePoint(*from, "--from", r.mutable_start());
  ParsePoint(*to, "--to", r.mutable_goal());
  if (const std::string* v = Option(a, "--radius")) r.set_robot_radius(Number(*v, "--radius"));
  if (const std::string* p = Option(a, "--prefer")) {
    if (*p == "clearance") r.set_prefer(v1::PlanPathRequest::PREFER_MAX_CLEARANCE);
    else if (*p == "shortest") r.set_prefer(v1::PlanPathRequest::PREFER_SHORTEST);
    else Usage("--prefer must be clearance or shortest");
  }
  r.set_min_version(MinVersion(a));
  v1::PlanPathResponse response;
  if (auto s = client.PlanPath(r, &response); !s.ok()) return Fail(s);
  if (a.json) {
    PrintJson(response);
  } else {
    std::cout << "path of " << response.path_size() << " points, length " << Num(response.length())
              << ", clearance at least " << Num(response.min_clearance()) << " (widest passage "
              << Num(response.best_clearance()) << "), version " << response.version() << "\n";
    for (const auto& p : response.path()) std::cout << Num(p.x()) << "," << Num(p.y()) << "\n";
  }
  if (const std::string* out = Option(a, "--output")) {
    v1::RenderImageRequest image;
    image.set_scene_id(a.scene);
    image.set_layer(v1::RenderImageRequest::LAYER_DISTANCE);
    image.set_draw_sites(true);
    image.set_min_version(response.version());
    *image.mutable_polyline() = response.path();
    v1::RenderImageResponse picture;
    if (auto s = client.RenderImage(image, &picture); !s.ok()) return Fail(s);
    if (int e = WriteBytes(*out, picture.image())) return e;
    std::cerr << "wrote " << *out << "\n";
  }
  return 0;
}

int Pick(const Args& a, Client& client) {
  const auto& w = a.words;
  if (w.size() != 3) Usage("usage: gvd pick X Y [--max-distance D]");
  v1::PickRequest r;
  r.set_scene_id(a.scene);
  r.mutable_point()->set_x(Number(w[1], "X"));
  r.mutable_point()->set_y(Number(w[2], "Y"));
  if (const std::string* d = Option(a, "--max-distance")) r.set_max_distance(Number(*d, "--max-distance"));
  v1::PickResponse response;
  if (auto s = client.Pick(r, &response); !s.ok()) return Fail(s);
  if (a.json) {
    PrintJson(response);
    return 0;
  }
  if (!response.found()) {
    std::cout << "(nothing within reach)\n";
    return 0;
  }
  std::string kind = response.feature_kind() == v1::FEATURE_KIND_EDGE    ? "edge"
                     : response.feature_kind() == v1::FEATURE_KIND_CURVE ? "curve"
                                                            : "vertex";
  std::cout << response.site_id() << "\t" << Num(response.distance()) << "\t" << kind << " "
            << response.feature_index() << "\n";
  return 0;
}

int Mosaic(const Args& a, Client& client) {
  const auto& w = a.words;
  if (w.size() != 3) Usage("usage: gvd mosaic IN OUT [--tiles N] [--adaptive] [--seed S] [--mean]");
  v1::RenderMosaicRequest r;
  if (const std::string* t = Option(a, "--tiles")) {
    uint32_t tiles;
    if (!absl::SimpleAtoi(*t, &tiles) || tiles == 0) {
      Usage(absl::StrCat("--tiles needs a positive count, not \"", *t, "\""));
    }
    r.set_tiles(tiles);
  }
  if (const std::string* s = Option(a, "--seed")) {
    uint64_t seed;
    if (!absl::SimpleAtoi(*s, &seed)) Usage(absl::StrCat("--seed needs a number, not \"", *s, "\""));
    r.set_seed(seed);
  }
  r.set_adaptive(Option(a, "--adaptive") != nullptr);
  r.set_mean(Option(a, "--mean") != nullptr);
  // The mosaic's format from OUT's name.
  const std::string& out = w[2];
  const std::string lower = absl::AsciiStrToLower(out);
  if (EndsWith(lower, ".png")) {
    r.set_format(v1::RenderMosaicRequest::FORMAT_PNG);
  } else if (EndsWith(lower, ".jpg") || EndsWith(lower, ".jpeg")) {
    r.set_format(v1::RenderMosaicRequest::FORMAT_JPEG);
  } else if (EndsWith(lower, ".webp")) {
    r.set_format(v1::RenderMosaicRequest::FORMAT_WEBP);
  } else if (EndsWith(lower, ".ppm") || EndsWith(lower, ".pgm") || EndsWith(lower, ".pnm")) {
    r.set_format(v1::RenderMosaicRequest::FORMAT_PNM);
  } else {
    Usage(absl::StrCat("OUT (", out, ") must end in .png, .jpg, .jpeg, .webp, .ppm, .pgm or .pnm"));
  }
  // The image's bytes, and the request holding them.
  std::string error;
  if (!ReadFileWithin(a, w[1], 2, r.mutable_image(), &error)) {
    return WriteFailed(absl::InvalidArgumentError(error));
  }
  const auto start = std::chrono::steady_clock::now();
  v1::RenderMosaicResponse response;
  if (auto s = client.RenderMosaic(r, &response); !s.ok()) return Fail(s);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (int e = WriteBytes(out, response.image())) return e;
  std::cout << "wrote " << out << ": " << response.width_px() << "x" << response.height_px() << ", "
            << response.sites_size() << (r.adaptive() ? " adaptive" : " random") << " tiles, "
            << (r.mean() ? "tile means" : "colours at the sites") << "; from the server in "
            << Num(std::round(seconds * 1000) / 1000) << " s\n";
  return 0;
}

}  // namespace gvd::cli

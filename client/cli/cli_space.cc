// The gvd tool's 3D side: a scene's distances written as an OpenVDB volume (volume SCENE -o
// OUT.vdb); models are read by model.h.
#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>

#include <cmath>
#include <iostream>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "client/cli/cli.h"

namespace gvd::cli {

void ParsePoint3(const std::string& text, v1::Point* p) {
  std::vector<std::string> c = absl::StrSplit(text, ',');
  if (c.size() != 3) Usage(absl::StrCat("points of a 3D site are X,Y,Z, not \"", text, "\""));
  p->set_x(Number(c[0], "X"));
  p->set_y(Number(c[1], "Y"));
  p->set_z(Number(c[2], "Z"));
}

// volume SCENE -o OUT.vdb [--window BOX] [--size WxHxD]: the scene's clearance field as an
// OpenVDB file: a float grid "distance" with every sample active, and an int grid "site"
// (the index of each sample's nearest site in the file's metadata "gvd_site_ids", -1 none).
int Volume(const Args& a, Client& client) {
  const auto& w = a.words;
  if (w.size() != 2) Usage("usage: gvd volume SCENE -o OUT.vdb [--window BOX] [--size WxHxD]");
  const std::string* out = Option(a, "--output");
  if (!out) Usage("volume needs -o OUT.vdb");
  v1::GetClearanceFieldRequest r;
  r.set_scene_id(w[1]);
  r.set_site_indices(true);
  if (const std::string* box = Option(a, "--window")) ParseWindow(*box, r.mutable_window());
  if (const std::string* size = Option(a, "--size")) {
    uint32_t width, height, depth;
    ParseSize(*size, &width, &height, &depth);
    if (depth == 0) Usage("volume's --size needs WIDTHxHEIGHTxDEPTH samples");
    r.set_width_px(width);
    r.set_height_px(height);
    r.set_depth_px(depth);
  }
  r.set_min_version(MinVersion(a));
  if (r.min_version() == 0) {  // the scene as it is now, once rendered
    v1::Scene scene;
    if (auto s = client.GetScene(w[1], &scene); !s.ok()) return Fail(s);
    if (scene.depth_px() == 0) {
      std::fprintf(stderr, "gvd: scene %s is 2D; volume needs a 3D scene\n", w[1].c_str());
      return 1;
    }
    r.set_min_version(scene.version());
  }
  v1::GetClearanceFieldResponse f;
  if (auto s = client.GetClearanceField(r, &f); !s.ok()) return Fail(s);
  const size_t n = size_t{f.width_px()} * f.height_px() * f.depth_px();
  if (size_t(f.clearance_size()) != n || size_t(f.ids_size()) != n) {
    std::fprintf(stderr, "gvd: the server answered %d distances and %d sites for %zu samples\n",
                 f.clearance_size(), f.ids_size(), n);
    return 1;
  }
  openvdb::initialize();
  const v1::Window& b = f.window();
  const double vx = (b.max_x() - b.min_x()) / f.width_px(), vy = (b.max_y() - b.min_y()) / f.height_px(),
               vz = (b.max_z() - b.min_z()) / f.depth_px();
  // Index (i, j, k) is the sample at the centre of cell (i, j, k) of the box.
  openvdb::math::Mat4d m = openvdb::math::Mat4d::identity();
  m.preScale(openvdb::math::Vec3d(vx, vy, vz));
  m.postTranslate(openvdb::math::Vec3d(b.min_x() + vx / 2, b.min_y() + vy / 2, b.min_z() + vz / 2));
  auto transform = openvdb::math::Transform::createLinearTransform(m);
  auto distance = openvdb::FloatGrid::create(std::numeric_limits<float>::infinity());
  auto site = openvdb::Int32Grid::create(-1);
  distance->setName("distance");
  site->setName("site");
  distance->setTransform(transform);
  site->setTransform(transform->copy());
  distance->setGridClass(openvdb::GRID_UNKNOWN);
  auto d_acc = distance->getAccessor();
  auto s_acc = site->getAccessor();
  size_t at = 0;
  for (uint32_t k = 0; k < f.depth_px(); ++k) {
    for (uint32_t j = 0; j < f.height_px(); ++j) {
      for (uint32_t i = 0; i < f.width_px(); ++i, ++at) {
        const openvdb::Coord c{static_cast<int>(i), static_cast<int>(j), static_cast<int>(k)};
        d_acc.setValueOn(c, f.clearance(static_cast<int>(at)));
        s_acc.setValueOn(c, static_cast<int32_t>(f.ids(static_cast<int>(at))) - 1);
      }
    }
  }
  std::string ids;
  for (const std::string& id : f.site_ids()) absl::StrAppend(&ids, ids.empty() ? "" : "\n", id);
  openvdb::GridPtrVec grids{distance, site};
  openvdb::MetaMap meta;
  meta.insertMeta("gvd_scene", openvdb::StringMetadata(w[1]));
  meta.insertMeta("gvd_version", openvdb::Int64Metadata(static_cast<int64_t>(f.version())));
  meta.insertMeta("gvd_site_ids", openvdb::StringMetadata(ids));
  try {
    openvdb::io::File file(*out);
    // No per-grid statistics: the box and the values are the request's, and their count
    // would run TBB's threads for nothing.
    file.setGridStatsMetadataEnabled(false);
    file.write(grids, meta);
    file.close();
  } catch (const openvdb::Exception& e) {
    std::fprintf(stderr, "gvd: cannot write %s: %s\n", out->c_str(), e.what());
    return 1;
  }
  std::cout << "wrote " << *out << ": " << f.width_px() << "x" << f.height_px() << "x"
            << f.depth_px() << " distances of scene " << w[1] << " at version " << f.version()
            << ", " << f.site_ids_size() << " sites\n";
  return 0;
}

}  // namespace gvd::cli

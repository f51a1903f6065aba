// The gvd command-line tool against the real server: the README's tour, files, errors.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <map>
#include <random>
#include <set>
#include <thread>
#include <vector>
#include <fstream>
#include <sstream>

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "gvd/client.h"
#include "render/kernel/exact2.h"
#include "tests/support/meshes3.h"
#include "tests/support/oracle3.h"
#include "tests/support/server_process.h"

namespace gvd {
namespace {

struct Result {
  int exit_code;
  std::string out;  // stdout and stderr together
};

class CliTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    server_ = new testing::ServerProcess(GVD_SERVER_PATH);
    ASSERT_TRUE(server_->error().empty()) << server_->error();
  }
  static void TearDownTestSuite() { delete server_; }

  static Result Gvd(const std::string& args) {
    return Run(std::string(GVD_CLI_PATH) + " --server " + server_->address() + " " + args);
  }
  static Result Run(const std::string& line) {
    std::string command = line + " 2>&1";
    FILE* p = popen(command.c_str(), "r");
    std::string out;
    char buf[4096];
    size_t n;
    while ((n = fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
    int status = pclose(p);
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
  }

  static std::string WriteFile(const std::string& name, const std::string& text) {
    std::string path = server_->dir() + "/" + name;
    std::ofstream(path) << text;
    return path;
  }

  static inline testing::ServerProcess* server_ = nullptr;
};

TEST_F(CliTest, TourFromTheReadme) {
  Result r = Gvd("scene create demo --window 0,0,100,100 --size 512x512");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("scene demo: window [0, 100] x [0, 100], 512x512 px"), std::string::npos)
      << r.out;
  r = Gvd("--scene demo sites add a 10 10 b 80 20 c 50 90");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("upserted 3 sites; scene demo is at version 2"), std::string::npos) << r.out;
  r = Gvd("--scene demo nearest 12 11 70 25 --min-version 2");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  std::istringstream lines(r.out);
  std::string header, line;
  std::getline(lines, header);
  EXPECT_EQ(header, "x\ty\tsite\tdistance\terror_bound\texact\tfeature");
  struct Expect {
    double x, y;
    const char* site;
    Vec2 at;
  };
  for (Expect e : {Expect{12, 11, "a", {10, 10}}, Expect{70, 25, "b", {80, 20}}}) {
    ASSERT_TRUE(std::getline(lines, line)) << r.out;
    std::istringstream f(line);
    double x, y, distance, bound;
    std::string site;
    f >> x >> y >> site >> distance >> bound;
    EXPECT_EQ(x, e.x);
    EXPECT_EQ(y, e.y);
    EXPECT_EQ(site, e.site);
    EXPECT_DOUBLE_EQ(distance, Distance({x, y}, e.at));
    EXPECT_GE(bound, 0);
    EXPECT_LT(bound, 1);
  }
  r = Gvd("--scene demo nearest 45 80 --exact");
  EXPECT_NE(r.out.find("45\t80\tc\t" ), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\t0\tyes\tvertex 0\n"), std::string::npos) << r.out;
  // a at (10, 10) is 5 from (13, 14): the closest point is a, the gradient (3, 4) / 5.
  r = Gvd("--scene demo nearest 13 14 --exact --closest");
  EXPECT_NE(r.out.find("\tfeature\tclosest\tgradient\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("13\t14\ta\t5\t0\tyes\tvertex 0\t10,10\t0.6,0.8\n"), std::string::npos)
      << r.out;
  r = Gvd("scene ls");
  EXPECT_NE(r.out.find("scene demo:"), std::string::npos) << r.out;
  r = Gvd("--scene demo sites ls");
  EXPECT_EQ(r.out, "a\t10\t10\nb\t80\t20\nc\t50\t90\n");
  r = Gvd("--scene demo sites rm b");
  EXPECT_EQ(r.exit_code, 0) << r.out;
  r = Gvd("--scene demo nearest 70 25 --min-version 3 --json");
  EXPECT_NE(r.out.find("\"site_id\": \"a\""), std::string::npos) << r.out;
  r = Gvd("scene rm demo");
  EXPECT_EQ(r.exit_code, 0) << r.out;
  r = Gvd("scene get demo");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("gvd: NOT_FOUND: scene \"demo\" does not exist"), std::string::npos) << r.out;
}

// Every kind from arguments and from GeoJSON; an image of the scene from `gvd render`.
TEST_F(CliTest, EveryKindAndAnImage) {
  ASSERT_EQ(Gvd("scene create kinds --window 0,0,10,10 --size 128x128").exit_code, 0);
  for (const char* add : {"segment s 1,1 4,2", "polyline l 1,8 3,9 5,8",
                          "polygon g 6,1 9,1 8,4 --side outside",
                          "bezier b 6,6 7,9 9,5 9,9 --tolerance 0.01",
                          "p 5 5 --multiplicative 2 --max-distance 3"}) {
    Result r = Gvd(std::string("--scene kinds sites add ") + add);
    ASSERT_EQ(r.exit_code, 0) << add << ": " << r.out;
  }
  std::string geo = WriteFile("kinds.geojson", R"({"type": "FeatureCollection", "features": [
    {"type": "Feature", "id": "gp", "geometry": {"type": "Point", "coordinates": [2, 5]}},
    {"type": "Feature", "properties": {"id": "gl", "additive_weight": 0.5},
     "geometry": {"type": "LineString", "coordinates": [[0, 0], [1, 3]]}},
    {"type": "Feature", "properties": {"id": "gg", "side": "inside"},
     "geometry": {"type": "Polygon", "coordinates": [[[3, 3], [5, 3], [4, 5], [3, 3]]]}},
    {"type": "Feature", "id": "holed",
     "geometry": {"type": "Polygon", "coordinates": [[[6, 6], [9, 6], [9, 9], [6, 9], [6, 6]],
                                                     [[7, 7], [7, 8], [8, 8], [8, 7], [7, 7]]]}}]})");
  Result r = Gvd("--scene kinds sites add --file " + geo);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  r = Gvd("--scene kinds sites ls");
  EXPECT_NE(r.out.find("g\tpolygon\t6,1\t9,1\t8,4\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("gg\tpolygon\t3,3\t5,3\t4,5\n"), std::string::npos) << r.out;
  // A polygon with a hole is one path site, its rings closed subpaths.
  EXPECT_NE(r.out.find("holed\tpath\tM 6,6 L 9,6 L 9,9 L 6,9 Z M 7,7 L 7,8 L 8,8 L 8,7 Z\n"),
            std::string::npos)
      << r.out;
  // Inside the hole, 0.2 from its left side: piece 4, from (7, 7) to (7, 8) (pieces 0-3 are
  // the outer ring's).
  r = Gvd("--scene kinds nearest 7.2 7.5 --exact");
  EXPECT_NE(r.out.find("\tholed\t"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\tedge 4\n"), std::string::npos) << r.out;
  r = Gvd("--scene kinds nearest 2.5 1.4 --exact");
  EXPECT_NE(r.out.find("\ts\t"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\tedge 0\n"), std::string::npos) << r.out;
  std::string png = server_->dir() + "/kinds.png";
  r = Gvd("render kinds -o " + png + " --layer features --draw-sites");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  std::ifstream in(png, std::ios::binary);
  std::string magic(8, '\0');
  in.read(magic.data(), 8);
  EXPECT_EQ(magic, "\x89PNG\r\n\x1a\n");
  r = Gvd("render kinds -o " + server_->dir() + "/kinds.exr --layer ids");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("INVALID_ARGUMENT: format FORMAT_EXR holds the LAYER_DISTANCE layer only"),
            std::string::npos)
      << r.out;
}

TEST_F(CliTest, SitesFromJsonAndTextFiles) {
  Result created = Gvd("scene create files --window -1,-1,1,1 --size 64x64 --render-mode exact");
  ASSERT_EQ(created.exit_code, 0) << created.out;
  EXPECT_NE(created.out.find("exact render"), std::string::npos) << created.out;
  std::string json = WriteFile("sites.json", R"([
    {"id": "left", "point": {"x": -0.5, "y": 0}},
    {"id": "right", "point": {"x": 0.5, "y": 0}}
  ])");
  Result r = Gvd("--scene files sites add --file " + json);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  std::string text = WriteFile("sites.txt", "# id x y\nup 0 0.75\ndown 0 -0.75\n");
  r = Gvd("--scene files sites add --file " + text);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("version 3"), std::string::npos) << r.out;
  r = Gvd("--scene files sites ls");
  EXPECT_EQ(r.out, "down\t0\t-0.75\nleft\t-0.5\t0\nright\t0.5\t0\nup\t0\t0.75\n");
  r = Gvd("--scene files nearest -0.9 0.1 0 0.9 --min-version 3");
  EXPECT_NE(r.out.find("\tleft\t"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\tup\t"), std::string::npos) << r.out;

  std::string bad = WriteFile("bad.txt", "a 1\n");
  r = Gvd("--scene files sites add --file " + bad);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("bad.txt:1: expected \"ID X Y\""), std::string::npos) << r.out;
}

// Every file the CLI reads keeps to --memory-limit: Assimp's OutOfMemory.off (309 bytes that
// declare 353,535,235,358 vertices) and a site list whose reading would pass the limit are
// refused by name, naming the limit, before anything reaches the server; a model of
// Assimp's invalid/ corpus that does read (malformed2.obj: five quads of a cube) is stored
// whole; a FeatureCollection without "features" is an error, not a crash.
TEST_F(CliTest, FilesAreReadWithinTheMemoryLimit) {
  ASSERT_EQ(Gvd("scene create limits --window 0,0,-1,4,4,2 --size 8x8x8").exit_code, 0);
  const std::string oom = "/usr/share/assimp/models/invalid/OutOfMemory.off";
  Result r = Gvd("--memory-limit 64 --scene limits sites add mesh oom --file " + oom);
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_EQ(r.out, "gvd: " + oom + ": reading it takes more than the memory limit of 64 MiB "
                   "(--memory-limit)\n");
  r = Gvd("--scene limits sites add mesh cube --file /usr/share/assimp/models/invalid/malformed2.obj");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  r = Gvd("--scene limits sites ls");
  EXPECT_NE(r.out.find("cube\tmesh\t"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\t10 triangles"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("oom"), std::string::npos) << r.out;
  ASSERT_EQ(Gvd("scene rm limits").exit_code, 0);

  // 2 MiB of sites: reading a site list takes up to 16 times its size, over 16 MiB.
  std::string big = "[";
  for (int i = 0; big.size() < (2u << 20); ++i) {
    big += absl::StrCat(i ? "," : "", R"({"id": "p)", i, R"(", "point": {"x": 0.5, "y": 0.5}})");
  }
  const std::string list = WriteFile("big.json", big + "]");
  r = Gvd("--memory-limit 16 sites add --file " + list);
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_EQ(r.out, "gvd: " + list + ": 2 MiB; using it takes up to 16 times its size, over the "
                   "memory limit of 16 MiB (--memory-limit)\n");
  r = Run("cat " + list + " | " + GVD_CLI_PATH + " --server " + server_->address() +
          " --memory-limit 16 sites add --file -");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_EQ(r.out, "gvd: standard input: more than 1 MiB; using it takes up to 16 times its "
                   "size, over the memory limit of 16 MiB (--memory-limit)\n");
  r = Gvd("--memory-limit 0 sites ls");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("--memory-limit needs a number of MiB from 1 to 2^40, not 0"),
            std::string::npos) << r.out;
  const std::string geo = WriteFile("nofeatures.geojson", R"({"type": "FeatureCollection"})");
  r = Gvd("sites add --file " + geo);
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_EQ(r.out, "gvd: " + geo + ": a FeatureCollection needs \"features\", an array\n");
}

TEST_F(CliTest, ErrorsAreReportedWithTheirStatus) {
  Result r = Gvd("scene create x --window 0,0,1,1 --size 0x10");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("gvd: INVALID_ARGUMENT: width_px is 0"), std::string::npos) << r.out;
  r = Gvd("--scene nowhere nearest 1 1");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("NOT_FOUND"), std::string::npos) << r.out;
  r = Gvd("nearest 1");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("usage"), std::string::npos) << r.out;
  r = Gvd("frobnicate");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("unknown command"), std::string::npos) << r.out;
}

// The structure and planning commands on a small scene: their output is checked against
// what the scene makes certain (three points: one triangle, three pairs).
TEST_F(CliTest, StructurePlanningAndPicking) {
  ASSERT_EQ(Gvd("scene create tri --window 0,0,1,1 --size 256x256").exit_code, 0);
  ASSERT_EQ(Gvd("--scene tri sites add a 0.2 0.2 b 0.8 0.25 c 0.5 0.8").exit_code, 0);
  Result r = Gvd("--scene tri neighbors --min-version 2");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("a b\na c\nb c\n"), std::string::npos) << r.out;
  r = Gvd("--scene tri neighbors c");
  EXPECT_NE(r.out.find("a c\nb c\n"), std::string::npos) << r.out;
  r = Gvd("--scene tri delaunay");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("a b c\n"), std::string::npos) << r.out;
  r = Gvd("--scene tri boundaries --method continuation");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("3 boundaries"), std::string::npos) << r.out;
  r = Gvd("--scene tri pick 0.21 0.2");
  {
    std::istringstream f(r.out);
    std::string site, kind;
    double distance;
    uint32_t index;
    f >> site >> distance >> kind >> index;
    EXPECT_EQ(site, "a") << r.out;
    EXPECT_EQ(distance, Distance({0.21, 0.2}, {0.2, 0.2})) << r.out;
    EXPECT_EQ(kind, "vertex");
  }
  r = Gvd("--scene tri pick 0.5 0.5 --max-distance 0.01");
  EXPECT_EQ(r.out, "(nothing within reach)\n");
  std::string path = server_->dir() + "/path.png";
  r = Gvd("--scene tri plan --from 0.05,0.05 --to 0.95,0.95 --radius 0.05 -o " + path);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("clearance at least"), std::string::npos) << r.out;
  std::ifstream in(path, std::ios::binary);
  std::string magic(8, '\0');
  in.read(magic.data(), 8);
  EXPECT_EQ(magic, "\x89PNG\r\n\x1a\n");
  r = Gvd("--scene tri plan --from 0.2,0.21 --to 0.9,0.9 --radius 0.05");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("NOT_FOUND: start (0.2, 0.21) is within robot_radius 0.05 of site \"a\""),
            std::string::npos)
      << r.out;
  for (const char* out : {"/zoom.png", "/clearance.exr"}) {
    std::string file = server_->dir() + out;
    r = Gvd(std::string("--scene tri ") +
            (out[1] == 'z' ? "zoom --window 0.4,0.2,0.6,0.3 --size 100x50 -o " : "clearance -o ") + file);
    ASSERT_EQ(r.exit_code, 0) << r.out;
    std::ifstream f(file, std::ios::binary);
    std::string head(4, '\0');
    f.read(head.data(), 4);
    EXPECT_EQ(head, out[1] == 'z' ? std::string("\x89PNG") : std::string("\x76\x2f\x31\x01")) << out;
  }
}

// A P6 PPM (which OpenImageIO reads and writes): width, height, then RGB bytes top row first.
struct Ppm {
  int w = 0, h = 0;
  std::vector<unsigned char> rgb;
  unsigned char* at(int x, int y) { return &rgb[(size_t(y) * w + x) * 3]; }
};

void WritePpm(const std::string& path, const Ppm& p) {
  std::ofstream out(path, std::ios::binary);
  out << "P6\n" << p.w << " " << p.h << "\n255\n";
  out.write(reinterpret_cast<const char*>(p.rgb.data()), std::streamsize(p.rgb.size()));
}

Ppm ReadPpm(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string magic;
  int max = 0;
  Ppm p;
  in >> magic >> p.w >> p.h >> max;
  in.get();
  p.rgb.resize(size_t(p.w) * p.h * 3);
  in.read(reinterpret_cast<char*>(p.rgb.data()), std::streamsize(p.rgb.size()));
  EXPECT_EQ(magic, "P6");
  return p;
}

// An image with a smooth left half (a gradient) and a detailed right half (noise): the
// server's mosaic, written where OUT says in the format its name says, keeps only colours of
// the image, one per tile; --adaptive puts its tiles where the detail is. (Each tile's colour
// against the exact diagram: tests/server/mosaic_server_test.cc.)
TEST_F(CliTest, MosaicsFromTheServer) {
  Ppm in{240, 160, {}};
  in.rgb.resize(240 * 160 * 3);
  std::mt19937 rng(2);
  for (int y = 0; y < in.h; ++y) {
    for (int x = 0; x < in.w; ++x) {
      unsigned char* p = in.at(x, y);
      if (x < in.w / 2) {
        p[0] = static_cast<unsigned char>(x * 2);
        p[1] = static_cast<unsigned char>(y);
        p[2] = 90;
      } else {
        p[0] = static_cast<unsigned char>(rng() % 256);
        p[1] = static_cast<unsigned char>(rng() % 256);
        p[2] = static_cast<unsigned char>(rng() % 256);
      }
    }
  }
  const std::string src = server_->dir() + "/photo.ppm";
  WritePpm(src, in);
  auto colours = [](Ppm& p, int x0, int x1) {
    std::set<std::array<unsigned char, 3>> c;
    for (int y = 0; y < p.h; ++y) {
      for (int x = x0; x < x1; ++x) c.insert({p.at(x, y)[0], p.at(x, y)[1], p.at(x, y)[2]});
    }
    return c;
  };
  std::set<std::array<unsigned char, 3>> all = colours(in, 0, in.w);
  std::map<std::string, Ppm> made;
  for (std::string how : {"random", "adaptive"}) {
    const std::string out = server_->dir() + "/mosaic-" + how + ".ppm";
    Result r = Gvd("mosaic " + src + " " + out + " --tiles 300 --seed 5" +
                   (how == "adaptive" ? " --adaptive" : ""));
    ASSERT_EQ(r.exit_code, 0) << how << ": " << r.out;
    EXPECT_NE(r.out.find("wrote " + out + ": 240x160, 300 " + how + " tiles, colours at the sites"),
              std::string::npos)
        << r.out;
    Ppm m = ReadPpm(out);
    ASSERT_EQ(m.w, in.w);
    ASSERT_EQ(m.h, in.h);
    auto used = colours(m, 0, m.w);
    EXPECT_LE(used.size(), 300u) << how;
    EXPECT_GT(used.size(), 200u) << how;
    for (const auto& c : used) ASSERT_TRUE(all.count(c)) << how << ": a colour not in the image";
    made[how] = m;
  }
  // Random tiles fall about evenly; adaptive ones crowd the noisy half.
  Ppm& random = made["random"];
  Ppm& adaptive = made["adaptive"];
  size_t random_left = colours(random, 0, 100).size(), random_right = colours(random, 140, 240).size();
  size_t adaptive_left = colours(adaptive, 0, 100).size(), adaptive_right = colours(adaptive, 140, 240).size();
  EXPECT_LT(random_right, 2 * random_left);
  EXPECT_GT(adaptive_right, 4 * adaptive_left);
  // OUT's name gives the format.
  const std::string png = server_->dir() + "/mean.png";
  Result r = Gvd("mosaic " + src + " " + png + " --tiles 50 --mean");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  std::ifstream written(png, std::ios::binary);
  std::string magic(8, '\0');
  written.read(magic.data(), 8);
  EXPECT_EQ(magic, "\x89PNG\r\n\x1a\n");
  // A bad input name, a bad flag, an unknown format and a file that is no image are clear
  // errors.
  r = Gvd("mosaic /nonexistent.png " + server_->dir() + "/x.png");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("cannot read /nonexistent.png"), std::string::npos) << r.out;
  r = Gvd("mosaic " + src + " " + server_->dir() + "/y.png --tiles -3");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("--tiles needs a positive count, not \"-3\""), std::string::npos) << r.out;
  r = Gvd("mosaic " + src + " " + server_->dir() + "/y.tga");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("must end in .png"), std::string::npos) << r.out;
  r = Gvd("mosaic " + WriteFile("notes.txt", "not an image") + " " + server_->dir() + "/z.png");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("INVALID_ARGUMENT: image is not a PNG"), std::string::npos) << r.out;
}

// gvd watch prints a line per event until the scene is deleted, then exits 0.
TEST_F(CliTest, WatchPrintsEventsUntilTheSceneIsDeleted) {
  ASSERT_EQ(Gvd("scene create watched --window 0,0,10,10 --size 64x64").exit_code, 0);
  const std::string out = server_->dir() + "/watch.txt";
  Result watch;
  std::thread t([&] { watch = Gvd("watch watched > " + out); });
  auto printed = [&] {
    std::ifstream in(out);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
  };
  // Its first line: the latest frame, the whole window changed, no sites yet.
  for (int i = 0; i < 600 && printed().empty(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_EQ(printed(), "version 1: changed [0, 10] x [0, 10], 0 sites\n");
  ASSERT_EQ(Gvd("--scene watched sites add a 5 5").exit_code, 0);
  for (int i = 0; i < 600 && printed().find("1 sites") == std::string::npos; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ASSERT_EQ(Gvd("scene rm watched").exit_code, 0);
  t.join();
  EXPECT_EQ(watch.exit_code, 0) << watch.out;
  const std::string text = printed();
  EXPECT_NE(text.find("\nversion 2: changed ["), std::string::npos) << text;
  EXPECT_NE(text.find("], 1 sites\nscene watched deleted\n"), std::string::npos) << text;
  EXPECT_EQ(Gvd("watch nowhere").exit_code, 1);
}

TEST_F(CliTest, HealthSaysServing) {
  Result r = Gvd("health");
  EXPECT_EQ(r.exit_code, 0) << r.out;
  EXPECT_EQ(r.out, "SERVING\n");
}

TEST_F(CliTest, UnreachableServerIsAClearError) {
  std::string command = std::string(GVD_CLI_PATH) + " --server 127.0.0.1:1 --timeout 2 scene ls 2>&1";
  FILE* p = popen(command.c_str(), "r");
  char buf[512] = {};
  size_t n = fread(buf, 1, sizeof buf - 1, p);
  int status = pclose(p);
  EXPECT_EQ(WEXITSTATUS(status), 1);
  EXPECT_NE(std::string(buf, n).find("UNAVAILABLE"), std::string::npos) << buf;
}

}  // namespace
}  // namespace gvd

namespace gvd {
namespace {

// A glTF file of one torus drawn twice, by two nodes with transforms of their own, and the
// mesh Assimp should make of it (the transforms applied). Coordinates are multiples of
// 2^-16 below 4, so that float and every transform below are exact.
struct Model {
  std::string gltf;
  MeshSite3 flattened;
};

Model TwoRings() {
  const MeshSite3 torus = Torus(0.6, 0.2, 24, 12);
  std::vector<Vec3> v;
  for (Vec3 p : torus.vertices) v.push_back(glm::round(p * 65536.0) / 65536.0);
  std::string buffer;
  for (Vec3 p : v) {
    for (int k = 0; k < 3; ++k) {
      const float f = static_cast<float>(p[k]);
      buffer.append(reinterpret_cast<const char*>(&f), 4);
    }
  }
  const size_t positions = buffer.size();
  for (const auto& t : torus.triangles) {
    for (uint32_t i : t) buffer.append(reinterpret_cast<const char*>(&i), 4);
  }
  Model m;
  m.gltf = absl::StrCat(R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1]}],
"nodes": [{"mesh": 0, "translation": [1.25, 2, 0.5]},
          {"mesh": 0, "translation": [3, 1.5, 1], "scale": [0.5, 0.5, 0.5]}],
"meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
"buffers": [{"byteLength": )", buffer.size(), R"(, "uri": "data:application/octet-stream;base64,)",
                        absl::Base64Escape(buffer), R"("}],
"bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": )", positions, R"(},
                {"buffer": 0, "byteOffset": )", positions, R"(, "byteLength": )",
                        buffer.size() - positions, R"(}],
"accessors": [{"bufferView": 0, "componentType": 5126, "count": )", v.size(),
                        R"(, "type": "VEC3", "min": [-0.8, -0.8, -0.2], "max": [0.8, 0.8, 0.2]},
              {"bufferView": 1, "componentType": 5125, "count": )", 3 * torus.triangles.size(),
                        R"(, "type": "SCALAR"}]})");
  std::vector<double> xyz;
  std::vector<uint32_t> tri;
  for (auto [offset, scale] : {std::pair{Vec3(1.25, 2, 0.5), 1.0}, {Vec3(3, 1.5, 1), 0.5}}) {
    const uint32_t base = static_cast<uint32_t>(xyz.size() / 3);
    for (Vec3 p : v) {
      const Vec3 w = p * scale + offset;
      xyz.insert(xyz.end(), {w.x, w.y, w.z});
    }
    for (const auto& t : torus.triangles) {
      for (uint32_t i : t) tri.push_back(base + i);
    }
  }
  m.flattened = Mesh(xyz, tri);
  return m;
}

// The 3D tour of client/README.md: a scene made by the CLI, a mesh loaded from a model file
// (its scene graph flattened), 10,000 nearest queries with closest points and gradients
// against the oracle, and the scene's distances written as an OpenVDB file that OpenVDB's
// Python reads back with the same values; a file Assimp cannot read, and a model over the
// server's limit, refused by name with nothing stored.
TEST_F(CliTest, A3DSceneFromAModelFileToOpenVdb) {
  const Model model = TwoRings();
  const std::string path = WriteFile("rings.gltf", model.gltf);
  Result r = Gvd("scene create model --window 0,0,-1,4,4,2 --size 24x24x18");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("box [0, 4] x [0, 4] x [-1, 2], 24x24x18 voxels"), std::string::npos)
      << r.out;
  r = Gvd("--scene model sites add mesh rings --file " + path);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("upserted 1 sites; scene model is at version 2"), std::string::npos) << r.out;
  r = Gvd("--scene model sites ls");
  EXPECT_NE(r.out.find("rings\tmesh\t"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\t1152 triangles"), std::string::npos) << r.out;

  // Sites of every 3D kind by their points; a query with z; a slice as an image.
  r = Gvd("--scene model sites add point p 2,2,1.5");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  r = Gvd("--scene model sites add triangle t 0,0,-1 0.5,0,-1 0,0.5,-1");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  r = Gvd("--scene model nearest 2 2 1.75 0.1 0.1 -1.5 --exact --min-version 4");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("2\t2\t1.75\tp\t0.25\t0\tyes\tvertex 0"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("0.1\t0.1\t-1.5\tt\t0.5\t0\tyes\tface 0"), std::string::npos) << r.out;
  r = Gvd("render model -o " + server_->dir() + "/slice.png --layer features --z 0.5");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("24x24 features of scene model, slice 9 (z 0.58333"), std::string::npos)
      << r.out;
  r = Gvd("--scene model sites rm p t");
  ASSERT_EQ(r.exit_code, 0) << r.out;

  // 10,000 queries in and around the box, against the oracle's distance to the flattened
  // model.
  auto client = Client::Connect(server_->address());
  v1::FindNearestRequest q;
  q.set_scene_id("model");
  q.set_min_version(5);
  for (auto f : {v1::NEAREST_FIELD_SITE, v1::NEAREST_FIELD_DISTANCE,
                 v1::NEAREST_FIELD_ERROR_BOUND, v1::NEAREST_FIELD_CLOSEST,
                 v1::NEAREST_FIELD_GRADIENT}) {
    q.add_fields(f);
  }
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-0.5, 4.5), uz(-1.5, 2.5);
  std::vector<Vec3> points;
  for (int i = 0; i < 10000; ++i) {
    points.push_back({u(rng), u(rng), uz(rng)});
    for (int k = 0; k < 3; ++k) q.add_xyz(points.back()[k]);
  }
  v1::FindNearestResponse answer;
  grpc::Status st = client->FindNearest(q, &answer);
  ASSERT_TRUE(st.ok()) << st.error_message();
  const v1::PackedNearest& p = answer.packed();
  ASSERT_EQ(p.distance_size(), 10000);
  int failures = 0;
  for (int i = 0; i < 10000 && failures < 10; ++i) {
    const Vec3 x = points[i];
    const double d = double(oracle3::ToGeometry(x, model.flattened));
    const Vec3 c(p.closest(3 * i), p.closest(3 * i + 1), p.closest(3 * i + 2));
    const Vec3 g(p.gradient(3 * i), p.gradient(3 * i + 1), p.gradient(3 * i + 2));
    const double tol = 1e-9 * (1 + d);
    const bool ok = p.distance(i) >= d - tol && p.distance(i) - d <= p.error_bound(i) + tol &&
                    double(oracle3::ToGeometry(c, model.flattened)) <= 1e-9 &&
                    std::abs(Distance(x, c) - p.distance(i)) <= tol &&
                    Length(g - (x - c) / Distance(x, c)) <= 1e-9;
    if (!ok) {
      ++failures;
      ADD_FAILURE() << "q " << x.x << "," << x.y << "," << x.z << ": " << p.distance(i)
                    << " bound " << p.error_bound(i) << ", oracle " << d;
    }
  }

  // The volume, as OpenVDB's Python reads it: the grid "distance", every voxel active,
  // index (0, 0, 0) at the first voxel's centre, the values of the clearance field.
  const std::string vdb = server_->dir() + "/model.vdb";
  r = Gvd("volume model -o " + vdb);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("24x24x18 distances of scene model at version 5"), std::string::npos) << r.out;
  const std::string dump = server_->dir() + "/model.txt";
  r = Run("/usr/bin/python3 -c \"import sys, pyopenvdb as vdb\n"
          "g = vdb.read(sys.argv[1], 'distance')\n"
          "m = vdb.readMetadata(sys.argv[1])\n"
          "out = open(sys.argv[2], 'w')\n"
          "print(g.activeVoxelCount(), *g.transform.indexToWorld((0, 0, 0)), m['gvd_site_ids'], file=out)\n"
          "a = g.getConstAccessor()\n"
          "for k in range(18):\n"
          "  for j in range(24):\n"
          "    for i in range(24): print(repr(a.getValue((i, j, k))), file=out)\n\" " +
          vdb + " " + dump);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  v1::GetClearanceFieldRequest fr;
  fr.set_scene_id("model");
  fr.set_min_version(5);
  v1::GetClearanceFieldResponse field;
  ASSERT_TRUE(client->GetClearanceField(fr, &field).ok());
  std::ifstream in(dump);
  size_t active;
  Vec3 origin;
  std::string ids;
  in >> active >> origin.x >> origin.y >> origin.z >> ids;
  EXPECT_EQ(active, 24u * 24 * 18);
  EXPECT_EQ(origin, Vec3(4.0 / 48, 4.0 / 48, -1 + 3.0 / 36));
  EXPECT_EQ(ids, "rings");
  ASSERT_EQ(field.clearance_size(), 24 * 24 * 18);
  for (int n = 0; n < field.clearance_size(); ++n) {
    double value;
    ASSERT_TRUE(in >> value) << n;
    ASSERT_EQ(float(value), field.clearance(n)) << n;
  }

  // A file Assimp cannot read; a model over the server's limit (a server of its own).
  const std::string junk = WriteFile("junk.obj", "this is not a model\n");
  r = Gvd("--scene model sites add mesh junk --file " + junk);
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find(junk + ": "), std::string::npos) << r.out;
  testing::ServerProcess small(GVD_SERVER_PATH, {"--max-triangles-per-mesh", "1000"});
  ASSERT_TRUE(small.error().empty()) << small.error();
  r = Run(std::string(GVD_CLI_PATH) + " --server " + small.address() +
          " scene create model --window 0,0,-1,4,4,2 --size 8x8x8");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  r = Run(std::string(GVD_CLI_PATH) + " --server " + small.address() +
          " --scene model sites add mesh rings --file " + path);
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("RESOURCE_EXHAUSTED: " + path + ": sites[0].mesh.triangles holds 1152 "
                       "triangles; the limit is 1000 (--max-triangles-per-mesh)"),
            std::string::npos)
      << r.out;
  r = Run(std::string(GVD_CLI_PATH) + " --server " + small.address() + " --scene model sites ls");
  EXPECT_EQ(r.exit_code, 0) << r.out;
  EXPECT_EQ(r.out, "");
  ASSERT_EQ(Gvd("scene rm model").exit_code, 0);
}

}  // namespace
}  // namespace gvd

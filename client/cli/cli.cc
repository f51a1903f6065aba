#include "client/cli/cli.h"

#include <google/protobuf/util/json_util.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstring>
#include <cstdio>
#include <fstream>
#include <iostream>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"

namespace gvd::cli {

const char* const kUsage = R"(usage: gvd [--server HOST:PORT] [--scene ID] [--json] [--timeout SECONDS] COMMAND

Scenes:
  gvd scene create ID --window MIN_X,MIN_Y,MAX_X,MAX_Y --size WIDTHxHEIGHT [--max-error E]
                     [--render-mode mesh|exact] [--diagram nearest|farthest]
  gvd scene create ID --window MIN_X,MIN_Y,MIN_Z,MAX_X,MAX_Y,MAX_Z --size WxHxD
      a 3D scene: a box sampled at the centres of W x H x D voxels
  gvd scene get ID
  gvd scene ls
  gvd scene rm ID
  gvd watch SCENE [--after VERSION]
      one line per frame the scene publishes from now on (after VERSION): its version,
      the window that changed and its site count; "deleted" and the end when the scene
      is deleted. --json prints each event as a line of JSON
Sites (of the scene named by --scene, default "default"):
  gvd sites add ID X Y [ID X Y ...]              points
  gvd sites add segment ID X,Y X,Y
  gvd sites add polyline ID X,Y X,Y [X,Y ...]
  gvd sites add polygon ID X,Y X,Y X,Y [X,Y ...] [--side outside|inside]
  gvd sites add bezier ID X,Y X,Y X,Y [X,Y] [--tolerance T]
      any of them with [--additive A] [--multiplicative M] [--max-distance R]
  gvd sites add point ID X,Y,Z                   3D sites, of a 3D scene
  gvd sites add segment ID X,Y,Z X,Y,Z
  gvd sites add triangle ID X,Y,Z X,Y,Z X,Y,Z
  gvd sites add mesh ID --file MODEL   the triangles of a model file (OBJ, STL, PLY, glTF,
                                       COLLADA, ...: what Assimp reads), instances and
                                       transforms applied
  gvd sites add --file PATH   JSON: [{"id": "a", "point": {"x": 1, "y": 2}}, ...] or
                              {"sites": [...]} (every kind: "segment", "polyline",
                              "polygon", "bezier", "path", as in the API); GeoJSON: a
                              FeatureCollection of Point, LineString, Polygon and
                              MultiPolygon features (a polygon with holes, or many, is
                              one path site), id from the feature's "id" or properties.id,
                              weights from properties additive_weight,
                              multiplicative_weight, max_distance, side; or text lines
                              "ID X Y"; PATH - reads stdin
  gvd sites rm ID [ID ...]
  gvd sites ls
Images:
  gvd render SCENE -o OUT [--layer ids|features|distance] [--format png|exr]
             [--window MIN_X,MIN_Y,MAX_X,MAX_Y] [--draw-sites] [--min-version V]
      writes the scene's frame once its current version is rendered (or from
      --min-version V on); the format follows OUT's extension unless given
  gvd render SCENE -o OUT --z Z | --slice K [--layer ...] [--window ...]
      a 3D scene's slice: the one holding Z, or slice K (0 at the box's min z)
  gvd volume SCENE -o OUT.vdb [--window MIN_X,MIN_Y,MIN_Z,MAX_X,MAX_Y,MAX_Z --size WxHxD]
      a 3D scene's distances as an OpenVDB file: a float grid "distance" with every
      sample active (a lower bound on the distance to the nearest site) and an int grid
      "site" (its index in the file's metadata gvd_site_ids, one id a line; -1 none); the
      scene's voxels, or W x H x D samples at the centres of the box's cells
Structure (paper sec. 5, 6), of the scene named by --scene:
  gvd boundaries [--window W] [--method full|continuation]
      the Voronoi boundaries as polylines, one per line: SITE_A SITE_B X,Y X,Y ...
      (SITE_A "-": where no site reaches)
  gvd neighbors [SITE] [--window W] [--coarse]
      Voronoi neighbour pairs (of SITE), refined by zoom windows where pixels are too
      coarse to tell (--coarse: as the pixels show them); sites that hold no pixel follow
  gvd delaunay [--coarse]
      the Delaunay triangles of a scene of points, one per line: A B C counter-clockwise
  gvd zoom -o OUT --window MIN_X,MIN_Y,MAX_X,MAX_Y --size WIDTHxHEIGHT [--layer ids|distance]
      renders any window at a resolution of its own and writes its ids (PNG, each site in
      the server's colour for it) or distances (EXR, or 16-bit PNG)
Applications (paper sec. 7):
  gvd clearance -o OUT [--window W --size WxH]
      the clearance field (distance to the nearest site, 0 inside solid polygons) as EXR
      floats, or a 16-bit PNG
  gvd plan --from X,Y --to X,Y [--radius R] [--prefer clearance|shortest] [-o OUT.png]
      a collision-free path of maximal clearance for a disc robot of radius R; OUT shows
      it over the distance field
  gvd pick X Y [--max-distance D]
      the site (and its feature) nearest to the point, exactly
  gvd mosaic IN OUT [--tiles N] [--adaptive] [--seed S] [--mean]
      IN (PNG, JPEG, WebP, GIF, BMP or PNM) as a Voronoi mosaic made by the server: N
      tiles (default 1000) at random, or --adaptive: more and smaller where the image has
      detail; each tile the colour at its site, or --mean of the tile; OUT's name says
      its format (.png, .jpg, .webp, .ppm)
  all of them wait for --min-version V when given
Health:
  gvd health           the server's grpc.health.v1 status; exit 0 when SERVING

Queries:
  gvd nearest X Y [X Y ...] [--min-version V] [--exact] [--closest]
      prints, per point, the nearest site, its exact distance, and the error bound: no
      site is closer than distance - error_bound; --exact certifies each answer exact;
      --closest adds the site's point nearest to X Y and the distance's unit gradient;
      a 3D scene's points are X Y Z

Flags:
  --server HOST:PORT   default 127.0.0.1:50051, or $GVD_SERVER
  --scene ID           default "default", or $GVD_SCENE
  --json               print responses as JSON
  --timeout SECONDS    per call (default 30)
  --token TOKEN        bearer token, or $GVD_TOKEN
  --tls-ca FILE        use TLS, trusting this CA (PEM); --tls-cert FILE --tls-key FILE add a
                       client certificate
  --memory-limit MIB   what reading one file may take (default 2048): a model is read in a
                       child process held to it; a site list (up to 16 times its size to
                       read), an image (twice) or a PEM file past it is refused unread
)";

[[noreturn]] void Usage(const std::string& message) {
  std::fprintf(stderr, "gvd: %s\n\n%s", message.c_str(), kUsage);
  std::exit(2);
}

double Number(const std::string& word, const std::string& what) {
  double v;
  if (!absl::SimpleAtod(word, &v)) Usage(absl::StrCat(what, " must be a number, not \"", word, "\""));
  return v;
}

// --window MIN_X,MIN_Y,MAX_X,MAX_Y.
void ParseWindow(const std::string& text, gvd::v1::Window* w) {
  std::vector<std::string> c = absl::StrSplit(text, ',');
  if (c.size() == 6) {  // a 3D box
    w->set_min_x(Number(c[0], "--window MIN_X"));
    w->set_min_y(Number(c[1], "--window MIN_Y"));
    w->set_min_z(Number(c[2], "--window MIN_Z"));
    w->set_max_x(Number(c[3], "--window MAX_X"));
    w->set_max_y(Number(c[4], "--window MAX_Y"));
    w->set_max_z(Number(c[5], "--window MAX_Z"));
    return;
  }
  if (c.size() != 4) {
    Usage(absl::StrCat("--window needs MIN_X,MIN_Y,MAX_X,MAX_Y (or MIN_X,MIN_Y,MIN_Z,MAX_X,MAX_Y,"
                       "MAX_Z for a 3D box), not ", text));
  }
  w->set_min_x(Number(c[0], "--window MIN_X"));
  w->set_min_y(Number(c[1], "--window MIN_Y"));
  w->set_max_x(Number(c[2], "--window MAX_X"));
  w->set_max_y(Number(c[3], "--window MAX_Y"));
}

int WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream file(path, std::ios::binary);
  file.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  file.close();
  if (file) return 0;
  std::fprintf(stderr, "gvd: cannot write %s\n", path.c_str());
  return 1;
}

int Fail(const grpc::Status& s) {
  static const char* kNames[] = {"OK", "CANCELLED", "UNKNOWN", "INVALID_ARGUMENT",
                                 "DEADLINE_EXCEEDED", "NOT_FOUND", "ALREADY_EXISTS",
                                 "PERMISSION_DENIED", "RESOURCE_EXHAUSTED", "FAILED_PRECONDITION",
                                 "ABORTED", "OUT_OF_RANGE", "UNIMPLEMENTED", "INTERNAL",
                                 "UNAVAILABLE", "DATA_LOSS", "UNAUTHENTICATED"};
  int code = s.error_code();
  std::fprintf(stderr, "gvd: %s: %s\n", code >= 0 && code <= 16 ? kNames[code] : "?",
               s.error_message().c_str());
  return 1;
}

void PrintJson(const google::protobuf::Message& m) {
  std::string out;
  google::protobuf::util::JsonPrintOptions options;
  options.add_whitespace = true;
  options.preserve_proto_field_names = true;
  (void)google::protobuf::util::MessageToJsonString(m, &out, options);
  std::cout << out;
}

// The shortest decimal form that reads back as v.
std::string Num(double v) {
  char buf[32];
  return std::string(buf, std::to_chars(buf, buf + sizeof buf, v).ptr);
}

void ParsePoint(const std::string& text, const std::string& flag, v1::Point* p) {
  std::vector<std::string> c = absl::StrSplit(text, ',');
  if (c.size() != 2) Usage(absl::StrCat(flag, " needs X,Y, not ", text));
  p->set_x(Number(c[0], flag + " X"));
  p->set_y(Number(c[1], flag + " Y"));
}

void ParseSize(const std::string& text, uint32_t* width, uint32_t* height, uint32_t* depth) {
  std::vector<std::string> n = absl::StrSplit(text, 'x');
  const bool three = depth != nullptr && n.size() == 3;
  if (depth != nullptr) *depth = 0;
  if ((n.size() != 2 && !three) || !absl::SimpleAtoi(n[0], width) ||
      !absl::SimpleAtoi(n[1], height) || (three && !absl::SimpleAtoi(n[2], depth))) {
    Usage(absl::StrCat("--size needs WIDTHxHEIGHT in pixels", depth ? " (or WxHxD voxels)" : "",
                       ", not ", text));
  }
}

const std::string* Option(const Args& a, const char* name) {
  auto it = a.options.find(name);
  return it == a.options.end() ? nullptr : &it->second;
}

uint64_t MinVersion(const Args& a) {
  const std::string* v = Option(a, "--min-version");
  if (!v) return 0;
  uint64_t mv;
  if (!absl::SimpleAtoi(*v, &mv)) Usage("--min-version needs a version number");
  return mv;
}

bool ReadFileWithin(const Args& a, const std::string& path, uint64_t factor, std::string* out,
                    std::string* error) {
  const uint64_t most = a.memory_limit / factor;
  const std::string name = path == "-" ? "standard input" : path;
  auto refuse = [&](const std::string& size) {
    *error = absl::StrCat(name, ": ", size, "; using it takes up to ", factor,
                          " times its size, over the memory limit of ", a.memory_limit >> 20,
                          " MiB (--memory-limit)");
    return false;
  };
  const int fd = path == "-" ? 0 : open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    *error = absl::StrCat("cannot read ", path, ": ", std::strerror(errno));
    return false;
  }
  struct stat st;
  const bool regular = fstat(fd, &st) == 0 && S_ISREG(st.st_mode);
  if (regular && static_cast<uint64_t>(st.st_size) > most) {
    if (fd != 0) close(fd);
    return refuse(absl::StrCat(static_cast<uint64_t>(st.st_size) >> 20, " MiB"));
  }
  out->clear();
  if (regular) out->reserve(static_cast<size_t>(st.st_size));
  char buffer[1 << 16];
  ssize_t n = 0;
  while ((n = read(fd, buffer, sizeof buffer)) != 0) {
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) break;
    if (out->size() + static_cast<size_t>(n) > most) {
      if (fd != 0) close(fd);
      return refuse(absl::StrCat("more than ", most >> 20, " MiB"));
    }
    out->append(buffer, static_cast<size_t>(n));
  }
  const int read_errno = errno;
  if (fd != 0) close(fd);
  if (n < 0) {
    *error = absl::StrCat("cannot read ", path, ": ", std::strerror(read_errno));
    return false;
  }
  return true;
}

}  // namespace gvd::cli

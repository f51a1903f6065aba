// Shared by the gvd command-line tool's source files: its arguments, usage, parsing of
// numbers, points and windows, and output.
#pragma once

#include <google/protobuf/message.h>
#include <grpcpp/support/status.h>

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "gvd/client.h"
#include "gvd/v1/voronoi.pb.h"

namespace gvd::cli {

struct Args {
  std::string server = "127.0.0.1:50051";
  std::string scene = "default";
  bool json = false;
  bool exact = false;
  double timeout = 30;
  std::string token, tls_ca, tls_cert, tls_key;
  // --memory-limit MIB: what reading one file (a model, a site list, an image) may take.
  uint64_t memory_limit = uint64_t{2048} << 20;
  std::map<std::string, std::string> options;  // command flags such as --window
  std::vector<std::string> words;
};

// Prints the message and the usage to stderr and exits with 2.
[[noreturn]] void Usage(const std::string& message);
// The usage text (gvd --help).
extern const char* const kUsage;

// The number in `word`, or Usage naming `what`.
double Number(const std::string& word, const std::string& what);
// MIN_X,MIN_Y,MAX_X,MAX_Y (of --window), or MIN_X,MIN_Y,MIN_Z,MAX_X,MAX_Y,MAX_Z (a 3D box).
void ParseWindow(const std::string& text, v1::Window* w);
// X,Y (of a flag such as --from).
void ParsePoint(const std::string& text, const std::string& flag, v1::Point* p);
// WIDTHxHEIGHT in pixels (of --size); with `depth`, also WIDTHxHEIGHTxDEPTH voxels (*depth
// is 0 when there are two numbers).
void ParseSize(const std::string& text, uint32_t* width, uint32_t* height,
               uint32_t* depth = nullptr);
// The value of a command flag, or null.
const std::string* Option(const Args& a, const char* name);
// --min-version V, or 0.
uint64_t MinVersion(const Args& a);
// The whole of the file at `path` ("-": standard input) as *out, where using it takes at most
// `factor` times its size, within --memory-limit: a larger file is refused before it is read
// (standard input once it has passed the size), false with *error naming the file and the limit.
bool ReadFileWithin(const Args& a, const std::string& path, uint64_t factor, std::string* out,
                    std::string* error);

// Prints "gvd: CODE: message" to stderr; returns 1.
int Fail(const grpc::Status& s);
void PrintJson(const google::protobuf::Message& m);
// Writes bytes (an image the server encoded) to `path`: 0, or prints "gvd: cannot write
// PATH" to stderr and returns 1.
int WriteBytes(const std::string& path, const std::string& bytes);
// The shortest decimal form that reads back as v.
std::string Num(double v);

// A command: its words and flags in `a`, its calls through `client`; returns the exit code.
using Command = int (*)(const Args& a, Client& client);

// The commands on a diagram's structure and its applications (cli_analysis.cc).
int Boundaries(const Args& a, Client& client);
int Neighbors(const Args& a, Client& client);
int Delaunay(const Args& a, Client& client);
int Zoom(const Args& a, Client& client);
int Clearance(const Args& a, Client& client);
int Plan(const Args& a, Client& client);
int Pick(const Args& a, Client& client);
int Mosaic(const Args& a, Client& client);

// The commands of 3D scenes (cli_space.cc): volume (a scene's distances as an OpenVDB file).
int Volume(const Args& a, Client& client);

// "X,Y,Z" (a 3D point of a command's words).
void ParsePoint3(const std::string& text, v1::Point* p);

}  // namespace gvd::cli

#include "client/cli/model.h"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <new>

#include "absl/strings/str_cat.h"

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define GVD_SANITIZED_ALLOCATOR 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(memory_sanitizer)
#define GVD_SANITIZED_ALLOCATOR 1
#endif
#endif
#ifdef GVD_SANITIZED_ALLOCATOR
// The sanitizers' allocator interface (<sanitizer/allocator_interface.h>, which gcc does not
// ship; its runtimes export these).
extern "C" {
int __sanitizer_install_malloc_and_free_hooks(void (*malloc_hook)(const volatile void*, size_t),
                                              void (*free_hook)(const volatile void*));
size_t __sanitizer_get_allocated_size(const volatile void* p);
}
#endif

namespace gvd::cli {
namespace {

// The child's answer on its pipe: a first byte saying how it ended, then the mesh (kMesh) or
// the error (kError).
constexpr char kMesh = 'M', kError = 'E', kOverLimit = 'L';

int child_out = -1;  // the child's end of the pipe

void WriteAll(int fd, const char* data, size_t size) {
  while (size > 0) {
    const ssize_t n = write(fd, data, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;
    data += n;
    size -= static_cast<size_t>(n);
  }
}

[[noreturn]] void OverLimit() {
  WriteAll(child_out, &kOverLimit, 1);
  _exit(0);
}

#ifdef GVD_SANITIZED_ALLOCATOR
int64_t held = 0, allowed = 0;  // the child is single-threaded
void OnAllocate(const volatile void*, size_t size) {
  held += static_cast<int64_t>(size);
  if (held > allowed) OverLimit();
}
void OnFree(const volatile void* p) {
  if (p != nullptr) held -= static_cast<int64_t>(__sanitizer_get_allocated_size(p));
}
#endif

// Keeps this (child) process to `limit` bytes more than it holds now and to `seconds` of CPU
// time; its faults end it with their own signal (not a handler inherited from the parent,
// such as a sanitizer's or a fuzzer's, which would report them as the parent's).
void Limit(uint64_t limit, uint32_t seconds) {
  for (int s : {SIGSEGV, SIGBUS, SIGABRT, SIGFPE, SIGILL, SIGXCPU, SIGALRM}) signal(s, SIG_DFL);
  const rlimit cpu{seconds, seconds + 1};
  setrlimit(RLIMIT_CPU, &cpu);
#ifdef GVD_SANITIZED_ALLOCATOR
  allowed = static_cast<int64_t>(std::min<uint64_t>(limit, INT64_MAX));
  __sanitizer_install_malloc_and_free_hooks(OnAllocate, OnFree);
#else
  uint64_t size_kb = 0;
  std::ifstream status("/proc/self/status");
  for (std::string key; status >> key;) {
    if (key == "VmSize:") {
      status >> size_kb;
      break;
    }
  }
  const rlimit r{static_cast<rlim_t>(size_kb * 1024 + limit), static_cast<rlim_t>(size_kb * 1024 + limit)};
  setrlimit(RLIMIT_AS, &r);
  // operator new calls this before it would throw: the limit, not a failure of the file.
  std::set_new_handler(OverLimit);
#endif
}

// The import itself (in the child).
bool Import(const ModelSource& source, v1::Mesh* mesh, std::string* error) {
  Assimp::Importer importer;
  // Points and lines are dropped (SortByPType with the removal below); polygons are split
  // into triangles; instances and node transforms are applied (PreTransformVertices).
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  const unsigned steps = aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                         aiProcess_SortByPType | aiProcess_PreTransformVertices;
  const aiScene* scene =
      source.bytes != nullptr
          ? importer.ReadFileFromMemory(source.bytes->data(), source.bytes->size(), steps,
                                        source.hint.c_str())
          : importer.ReadFile(source.path, steps);
  if (scene == nullptr) {
    *error = absl::StrCat(source.path, ": cannot read it as a model: ", importer.GetErrorString());
    return false;
  }
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* part = scene->mMeshes[m];
    const uint32_t base = static_cast<uint32_t>(mesh->xyz_size() / 3);
    for (unsigned v = 0; v < part->mNumVertices; ++v) {
      const aiVector3D& p = part->mVertices[v];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
        *error = absl::StrCat(source.path, ": mesh ", m, ", vertex ", v, " is not finite");
        return false;
      }
      mesh->add_xyz(p.x);
      mesh->add_xyz(p.y);
      mesh->add_xyz(p.z);
    }
    for (unsigned f = 0; f < part->mNumFaces; ++f) {
      const aiFace& face = part->mFaces[f];
      if (face.mNumIndices != 3) continue;
      for (unsigned k = 0; k < 3; ++k) {
        if (face.mIndices[k] >= part->mNumVertices) {
          *error = absl::StrCat(source.path, ": mesh ", m, ", face ", f, " names vertex ",
                                face.mIndices[k], " of ", part->mNumVertices);
          return false;
        }
        mesh->add_triangles(base + face.mIndices[k]);
      }
    }
  }
  if (mesh->triangles_size() == 0) {
    *error = absl::StrCat(source.path, ": the model has no triangles");
    return false;
  }
  return true;
}

[[noreturn]] void Child(const ModelSource& source, const ModelLimits& limits, int out) {
  child_out = out;
  Limit(limits.memory_bytes, limits.cpu_seconds);
  v1::Mesh mesh;
  std::string error;
  std::string answer(1, kError);
  if (Import(source, &mesh, &error)) {
    answer[0] = kMesh;
    mesh.AppendToString(&answer);
  } else {
    answer += error;
  }
  WriteAll(out, answer.data(), answer.size());
  _exit(0);
}

std::string Mib(uint64_t bytes) { return absl::StrCat(bytes >> 20, " MiB"); }

}  // namespace

bool ReadModel(const ModelSource& source, const ModelLimits& limits, v1::Mesh* mesh,
               std::string* error) {
  const uint64_t limit_bytes = limits.memory_bytes;
  const std::string limit = absl::StrCat("the memory limit of ", Mib(limit_bytes), " (--memory-limit)");
  if (source.bytes == nullptr) {
    struct stat st;
    if (stat(source.path.c_str(), &st) != 0) {
      *error = absl::StrCat(source.path, ": ", std::strerror(errno));
      return false;
    }
    // Assimp reads a file whole before it parses it.
    if (static_cast<uint64_t>(st.st_size) > limit_bytes) {
      *error = absl::StrCat(source.path, ": ", Mib(st.st_size), ", over ", limit);
      return false;
    }
  }
  int pipe_fds[2];
  if (pipe2(pipe_fds, O_CLOEXEC) != 0) {
    *error = absl::StrCat(source.path, ": cannot start its import: ", std::strerror(errno));
    return false;
  }
  const pid_t pid = fork();
  if (pid < 0) {
    *error = absl::StrCat(source.path, ": cannot start its import: ", std::strerror(errno));
    close(pipe_fds[0]);
    close(pipe_fds[1]);
    return false;
  }
  if (pid == 0) {
    close(pipe_fds[0]);
    Child(source, limits, pipe_fds[1]);
  }
  close(pipe_fds[1]);
  // The mesh was built within the limit, so its encoding is no larger.
  std::string answer;
  char buffer[1 << 16];
  bool too_long = false;
  for (;;) {
    const ssize_t n = read(pipe_fds[0], buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    if (answer.size() + static_cast<size_t>(n) > limit_bytes + 1) {
      too_long = true;
      kill(pid, SIGKILL);
      break;
    }
    answer.append(buffer, static_cast<size_t>(n));
  }
  close(pipe_fds[0]);
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (too_long || (!answer.empty() && answer[0] == kOverLimit)) {
    *error = absl::StrCat(source.path, ": reading it takes more than ", limit);
    return false;
  }
  if (WIFSIGNALED(status) && WTERMSIG(status) == SIGXCPU && answer.empty()) {
    *error = absl::StrCat(source.path, ": reading it takes more than ", limits.cpu_seconds,
                          " s of CPU time, the model importer's limit");
    return false;
  }
  if (WIFSIGNALED(status)) {
    *error = absl::StrCat(source.path, ": the model importer died reading it (",
                          strsignal(WTERMSIG(status)), "), within ", limit);
    return false;
  }
  if (answer.empty() || (answer[0] != kMesh && answer[0] != kError)) {
    *error = absl::StrCat(source.path, ": the model importer ended without an answer");
    return false;
  }
  if (answer[0] == kError) {
    *error = answer.substr(1);
    return false;
  }
  if (!mesh->ParseFromArray(answer.data() + 1, static_cast<int>(answer.size() - 1))) {
    *error = absl::StrCat(source.path, ": the model importer's answer does not decode");
    return false;
  }
  return true;
}

}  // namespace gvd::cli

// Model files (OBJ, STL, PLY, glTF, COLLADA, ...: what Assimp reads) as a mesh of triangles,
// read where no file can take the machine down or the reader with it.
//
// Assimp believes the counts a file declares: Assimp's own invalid/OutOfMemory.off, 309
// bytes, declares 353,535,235,358 vertices, and a reader in process would allocate them. So
// the import runs in a child process (fork) that keeps to a memory limit: the address space
// it may add (RLIMIT_AS), or under ASan, whose shadow memory needs an address space of
// terabytes, the bytes its allocations hold (the allocation hooks; TSan maps an allocation's
// shadow before its hook runs, so under TSan the limit does not hold); and CPU
// time (RLIMIT_CPU). A file the import cannot finish within the limits, or that makes the
// importer die, is refused with an error naming the file and the limit, as is an unreadable
// one; what comes back is checked
// (every triangle's corners among the mesh's vertices, every coordinate finite).
#pragma once

#include <cstdint>
#include <string>

#include "gvd/v1/voronoi.pb.h"

namespace gvd::cli {

// Where the model comes from: a file by its path (Assimp reads the files it names, such as a
// glTF's buffers, beside it), or bytes in memory whose format Assimp finds from their
// contents (`hint`, an extension such as "obj", helps where they carry no signature).
struct ModelSource {
  std::string path;             // the file; in messages, the name of the bytes otherwise
  const std::string* bytes = nullptr;
  std::string hint;
};

// What the child may take: memory beyond what it starts with, and CPU time (a few bytes of
// PLY can keep Assimp in a loop).
struct ModelLimits {
  uint64_t memory_bytes = uint64_t{2048} << 20;
  uint32_t cpu_seconds = 300;
};

// The model's triangles as `mesh` (its scene graph flattened with its transforms; points and
// lines dropped), read in a child process held to `limits`. False with *error naming the
// source (and the limit, when that is the cause).
bool ReadModel(const ModelSource& source, const ModelLimits& limits, v1::Mesh* mesh,
               std::string* error);

}  // namespace gvd::cli

// Shader programs from the embedded shader files (render/gl/shaders/*.glsl): compiled and
// linked, with the failure's log in the error. Needs the thread's current GL context.
#pragma once

#include "absl/status/statusor.h"
#include "render/gl/objects.h"

namespace gvd::gl {

// A program of a vertex and a fragment shader.
absl::StatusOr<Program> LinkProgram(const char* vertex, const char* fragment);
// A compute program.
absl::StatusOr<Program> LinkCompute(const char* compute);

// The location of a uniform of the program (-1 when the program has none by that name).
int Uniform(const Program& program, const char* name);

}  // namespace gvd::gl

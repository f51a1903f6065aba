#include "render/gl/program.h"

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <initializer_list>
#include <string>

#include "absl/strings/str_cat.h"
#include "render/gl/shaders.h"

namespace gvd::gl {
namespace {

absl::StatusOr<Shader> Compile(GLenum stage, const char* text) {
  // The one file shaders share, put in place of its #include line.
  std::string source = text;
  const std::string include = "#include \"segments.glsl\"\n";
  if (size_t at = source.find(include); at != std::string::npos) {
    source.replace(at, include.size(), shaders::kSegments);
  }
  const char* sources[] = {source.c_str()};
  Shader shader = Shader::Create(stage);
  glShaderSource(shader.id(), 1, sources, nullptr);
  glCompileShader(shader.id());
  GLint ok = 0;
  glGetShaderiv(shader.id(), GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetShaderInfoLog(shader.id(), sizeof log, nullptr, log);
    return absl::InternalError(absl::StrCat("shader compilation failed: ", log));
  }
  return shader;
}

// Links the compiled stages into a program.
absl::StatusOr<Program> Link(std::initializer_list<std::pair<GLenum, const char*>> stages) {
  std::vector<Shader> compiled;
  for (const auto& [stage, text] : stages) {
    auto shader = Compile(stage, text);
    if (!shader.ok()) return shader.status();
    compiled.push_back(std::move(*shader));
  }
  Program program = Program::Create();
  for (const Shader& s : compiled) glAttachShader(program.id(), s.id());
  glLinkProgram(program.id());
  GLint ok = 0;
  glGetProgramiv(program.id(), GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetProgramInfoLog(program.id(), sizeof log, nullptr, log);
    return absl::InternalError(absl::StrCat("shader link failed: ", log));
  }
  return program;  // the shaders go now; the program keeps what it linked
}

}  // namespace

absl::StatusOr<Program> LinkProgram(const char* vertex, const char* fragment) {
  return Link({{GL_VERTEX_SHADER, vertex}, {GL_FRAGMENT_SHADER, fragment}});
}

absl::StatusOr<Program> LinkCompute(const char* compute) {
  return Link({{GL_COMPUTE_SHADER, compute}});
}

int Uniform(const Program& program, const char* name) {
  return glGetUniformLocation(program.id(), name);
}

}  // namespace gvd::gl

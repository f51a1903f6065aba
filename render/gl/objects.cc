#include "render/gl/objects.h"

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

namespace gvd::gl {

template <Kind K>
Object<K> Object<K>::Create(unsigned shader_stage) {
  (void)shader_stage;  // for shaders only
  GLuint id = 0;
  if constexpr (K == Kind::kBuffer) glGenBuffers(1, &id);
  if constexpr (K == Kind::kFramebuffer) glGenFramebuffers(1, &id);
  if constexpr (K == Kind::kRenderbuffer) glGenRenderbuffers(1, &id);
  if constexpr (K == Kind::kVertexArray) glGenVertexArrays(1, &id);
  if constexpr (K == Kind::kProgram) id = glCreateProgram();
  if constexpr (K == Kind::kShader) id = glCreateShader(shader_stage);
  return Object(id);
}

template <Kind K>
void Object<K>::Reset() {
  if (id_ == 0) return;
  if constexpr (K == Kind::kBuffer) glDeleteBuffers(1, &id_);
  if constexpr (K == Kind::kFramebuffer) glDeleteFramebuffers(1, &id_);
  if constexpr (K == Kind::kRenderbuffer) glDeleteRenderbuffers(1, &id_);
  if constexpr (K == Kind::kVertexArray) glDeleteVertexArrays(1, &id_);
  if constexpr (K == Kind::kProgram) glDeleteProgram(id_);
  if constexpr (K == Kind::kShader) glDeleteShader(id_);
  id_ = 0;
}

template class Object<Kind::kBuffer>;
template class Object<Kind::kFramebuffer>;
template class Object<Kind::kRenderbuffer>;
template class Object<Kind::kVertexArray>;
template class Object<Kind::kProgram>;
template class Object<Kind::kShader>;

}  // namespace gvd::gl

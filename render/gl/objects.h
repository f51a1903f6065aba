// GL objects owned by C++ objects: each wrapper holds one GL name, deletes it when it goes,
// and moves but never copies (as Magnum's GL wrappers do), so that no path can leak or
// double-delete a buffer, a framebuffer or a program. Everything here needs the thread's
// current GL context (GlContext), the one the object was made on.
#pragma once

#include <utility>

namespace gvd::gl {

enum class Kind { kBuffer, kFramebuffer, kRenderbuffer, kVertexArray, kProgram, kShader };

// One GL name of kind K; 0 (empty) after a move or before Create.
template <Kind K>
class Object {
 public:
  Object() = default;
  // A new name: glGen* / glCreate* (a shader's stage given as its GLenum).
  static Object Create(unsigned shader_stage = 0);
  ~Object() { Reset(); }
  Object(Object&& other) noexcept : id_(std::exchange(other.id_, 0)) {}
  Object& operator=(Object&& other) noexcept {
    if (this != &other) {
      Reset();
      id_ = std::exchange(other.id_, 0);
    }
    return *this;
  }
  Object(const Object&) = delete;
  Object& operator=(const Object&) = delete;

  unsigned id() const { return id_; }
  explicit operator bool() const { return id_ != 0; }

 private:
  explicit Object(unsigned id) : id_(id) {}
  void Reset();  // deletes the name, if any
  unsigned id_ = 0;
};

using Buffer = Object<Kind::kBuffer>;
using Framebuffer = Object<Kind::kFramebuffer>;
using Renderbuffer = Object<Kind::kRenderbuffer>;
using VertexArray = Object<Kind::kVertexArray>;
using Program = Object<Kind::kProgram>;
using Shader = Object<Kind::kShader>;

}  // namespace gvd::gl

#version 450 core
// Writes a computed render (nearest.comp's ids and values) into the id and depth buffers,
// so that later draws meet it in the depth test as if its sites had been drawn.
layout(std430, binding = 4) readonly buffer Ids { uint ids[]; };
layout(std430, binding = 5) readonly buffer Values { float values[]; };
uniform uint u_width;
uniform float u_inv_depth;
layout(location = 0) out uint o_site;
void main() {
  uint i = uint(gl_FragCoord.y) * u_width + uint(gl_FragCoord.x);
  uint id = ids[i];
  if (id == 0u) discard;  // the cleared buffers hold nothing there already
  gl_FragDepth = values[i] * u_inv_depth;
  o_site = id;
}

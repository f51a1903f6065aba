#version 450 core
layout(std430, binding = 0) readonly buffer Segments { vec4 segments[]; };
flat in uvec4 v_info;
flat in vec3 v_weight;
flat in vec4 v_first;
uniform vec2 u_pixel;
uniform vec2 u_origin;
uniform float u_inv_depth;
uniform float u_margin;
layout(location = 0) out uint o_site;
#include "segments.glsl"
void main() {
  p = (gl_FragCoord.xy - u_origin) * u_pixel;  // the grid's pixel (0, 0) is at u_origin
  d = 3.0e38;
  winding = 0;
  visit(v_first);  // a point's only segment comes with the instance: no buffer read
  for (uint i = v_info.y + 1u; i < v_info.y + v_info.z; ++i) visit(segments[i]);
  if (d > v_weight.z) discard;
  if (wrong_side(v_info.w)) discard;
  gl_FragDepth = (v_weight.x * d + v_weight.y) * u_inv_depth;
  o_site = v_info.x;
}

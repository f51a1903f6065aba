#version 450 core
flat in uint v_site;
flat in vec2 v_point;
flat in vec2 v_weight;
uniform vec2 u_pixel;
uniform vec2 u_origin;
uniform float u_inv_depth;
layout(location = 0) out uint o_site;
void main() {
  vec2 p = (gl_FragCoord.xy - u_origin) * u_pixel;
  gl_FragDepth = (v_weight.x * length(p - v_point) + v_weight.y) * u_inv_depth;
  o_site = v_site;
}

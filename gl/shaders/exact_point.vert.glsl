#version 450 core
// Points with no max_distance, per fragment: instanced squares of half side r around each
// point (rect = (x, y, r)), weight = (m, a); nothing to discard, no buffer to read, so the
// fragment is one distance. The square's corners, sqrt(2) r away, bound what it writes.
layout(location = 0) in vec3 unit;
layout(location = 1) in vec3 square;
layout(location = 2) in vec2 weight;
layout(location = 3) in uint site;
uniform vec2 u_scale;
flat out uint v_site;
flat out vec2 v_point;
flat out vec2 v_weight;
void main() {
  vec2 p = square.xy + square.z * (2.0 * unit.xy - 1.0);
  gl_Position = vec4(p * u_scale - 1.0, 0.0, 1.0);
  v_site = site;
  v_point = square.xy;
  v_weight = weight;
}

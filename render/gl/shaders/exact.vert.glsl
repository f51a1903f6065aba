#version 450 core
// Per-fragment sites, instanced quads: `rect` = (x0, y0, x1, y1), `weight` = (m, a, reach),
// `first` = the site's first segment (also in the buffer), `info` = (site, index of the first
// segment, segment count, side as segments.glsl says). The fragment takes the least distance
// over the site's segments (a point is one of length 0), tests a polygon's or a path's side
// by its rule, and writes m d + a as depth.
layout(location = 0) in vec3 unit;
layout(location = 1) in vec4 rect;
layout(location = 2) in vec3 weight;
layout(location = 3) in vec4 first;
layout(location = 4) in uvec4 info;
uniform vec2 u_scale;
flat out uvec4 v_info;
flat out vec3 v_weight;
flat out vec4 v_first;
void main() {
  vec2 p = mix(rect.xy, rect.zw, unit.xy);
  gl_Position = vec4(p * u_scale - 1.0, 0.0, 1.0);
  v_info = info;
  v_weight = weight;
  v_first = first;
}

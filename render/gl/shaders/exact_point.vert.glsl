#version 450 core
// Points with no max_distance, per fragment: instanced rectangles rect = (x0, y0, x1, y1)
// around each point (a square of half side r, cut to the site's clip), weight = (m, a);
// nothing to discard, no buffer to read, so the fragment is one distance. The square's
// corners, sqrt(2) r away, bound what it writes.
layout(location = 0) in vec3 unit;
layout(location = 1) in vec4 rect;
layout(location = 2) in vec2 point;
layout(location = 3) in vec2 weight;
layout(location = 4) in uint site;
uniform vec2 u_scale;
flat out uint v_site;
flat out vec2 v_point;
flat out vec2 v_weight;
void main() {
  vec2 p = mix(rect.xy, rect.zw, unit.xy);
  gl_Position = vec4(p * u_scale - 1.0, 0.0, 1.0);
  v_site = site;
  v_point = point;
  v_weight = weight;
}

#version 450 core
// Vertex cones, instanced: `unit` is a vertex of the unit cone, `cone` = (x, y, rho),
// `weight` = (m, a), `site` = slot + 1, `clip` = the rectangle (x0, y0, x1, y1) outside which
// none of the site's pixels lie. Height m * rho * z + a.
layout(location = 0) in vec3 unit;
layout(location = 1) in vec3 cone;
layout(location = 2) in vec2 weight;
layout(location = 3) in vec4 clip;
layout(location = 4) in uint site;
uniform vec2 u_scale;
uniform float u_inv_depth;
out float gl_ClipDistance[4];
flat out uint v_site;
void main() {
  vec2 p = cone.xy + cone.z * unit.xy;
  float value = weight.x * cone.z * unit.z + weight.y;
  gl_Position = vec4(p * u_scale - 1.0, value * u_inv_depth, 1.0);
  gl_ClipDistance[0] = p.x - clip.x;
  gl_ClipDistance[1] = p.y - clip.y;
  gl_ClipDistance[2] = clip.z - p.x;
  gl_ClipDistance[3] = clip.w - p.y;
  v_site = site;
}

#version 450 core
// Half-tents of edges, instanced: `unit` = (u, v, unused) spans the part of the segment from
// range.x to range.y (fractions of it: u in [0, 1]) and its left normal (v in [0, 1]);
// `ends` = (a, b), `tent` = (width r, m, a), `clip` as in cone.vert. A half is a plane, so
// the interpolated height is the distance to the segment's line, exactly. Vertices with
// v = -1 make a strip u_overhang wide on the segment's other side, whose height is the
// distance to the line there (a plane too): the two halves of a tent are cut and snapped
// apart (clip planes, ranges), so their edges along the line need not meet, and a pixel
// centre within a snap of the line would otherwise fall between them.
layout(location = 0) in vec3 unit;
layout(location = 1) in vec4 ends;
layout(location = 2) in vec3 tent;
layout(location = 3) in vec4 clip;
layout(location = 4) in vec2 range;
layout(location = 5) in uint site;
uniform vec2 u_scale;
uniform float u_inv_depth;
uniform float u_overhang;
out float gl_ClipDistance[4];
flat out uint v_site;
void main() {
  vec2 ab = ends.zw - ends.xy;
  vec2 n = vec2(-ab.y, ab.x) / length(ab);
  float offset = unit.y >= 0.0 ? unit.y * tent.x : -u_overhang;  // to the left of ab
  vec2 p = ends.xy + mix(range.x, range.y, unit.x) * ab + offset * n;
  float value = tent.y * abs(offset) + tent.z;
  gl_Position = vec4(p * u_scale - 1.0, value * u_inv_depth, 1.0);
  gl_ClipDistance[0] = p.x - clip.x;
  gl_ClipDistance[1] = p.y - clip.y;
  gl_ClipDistance[2] = clip.z - p.x;
  gl_ClipDistance[3] = clip.w - p.y;
  v_site = site;
}

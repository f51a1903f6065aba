#version 450 core
// A full render of a nearest diagram from per-tile candidate lists (Rasterizer::Compute):
// one work group per tile of 8x8 pixels, one invocation per pixel. Each pixel takes the
// least value over its tile's candidates present there, ties to the lower site: the
// distance to each plain point (as exact_point.frag computes it), then m d + a for the
// other sites, computed as exact.frag computes it (the least distance over the site's
// segments, a point being one of length 0; the polygon's side by the even-odd rule). It
// writes the site (slot + 1; 0 and u_none where no candidate is present) and its value.
layout(local_size_x = 8, local_size_y = 8) in;
struct Site {
  vec4 first;   // the first segment (a, b)
  vec4 weight;  // (m, a, reach, unused)
  uvec4 info;   // (site, index of the first segment, segment count, side as segments.glsl says)
};
layout(std430, binding = 0) readonly buffer Segments { vec4 segments[]; };
layout(std430, binding = 1) readonly buffer Sites { Site sites[]; };
struct Point {
  vec2 p;
  uint site;
  uint unused;
};
// Tile t's points are points[offsets[3t] .. offsets[3t + 3]), the sites it scans whole
// sites[candidates[k]] for k in [offsets[3t + 1], offsets[3t + 4]), and single segments of
// the other sites pieces[k] = (site, segment) for k in [offsets[3t + 2], offsets[3t + 5]):
// each is taken as a site of its own, which gives the site's least value over them.
layout(std430, binding = 2) readonly buffer Offsets { uint offsets[]; };
layout(std430, binding = 3) readonly buffer Candidates { uint candidates[]; };
layout(std430, binding = 7) readonly buffer Pieces { uvec2 pieces[]; };
layout(std430, binding = 4) writeonly buffer Ids { uint ids[]; };
layout(std430, binding = 5) writeonly buffer Values { float values[]; };
layout(std430, binding = 6) readonly buffer Points { Point points[]; };
uniform uvec2 u_size;   // the grid's pixels
uniform vec2 u_pixel;   // a pixel's size
uniform float u_margin;
uniform float u_none;   // the value where no site is present
#include "segments.glsl"
void main() {
  uvec2 px = gl_GlobalInvocationID.xy;
  if (px.x >= u_size.x || px.y >= u_size.y) return;
  p = (vec2(px) + 0.5) * u_pixel;
  uint tile = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  float best = 3.0e38;
  uint id = 0u;
  uint at = 3u * tile;
  for (uint k = offsets[at]; k < offsets[at + 3u]; ++k) {
    Point q = points[k];
    float value = length(p - q.p);
    if (value < best || (value == best && q.site < id)) {
      best = value;
      id = q.site;
    }
  }
  for (uint k = offsets[at + 1u]; k < offsets[at + 4u]; ++k) {
    Site s = sites[candidates[k]];
    d = 3.0e38;
    winding = 0;
    visit(s.first);
    for (uint i = s.info.y + 1u; i < s.info.y + s.info.z; ++i) visit(segments[i]);
    if (d > s.weight.z) continue;
    if (wrong_side(s.info.w)) continue;
    float value = s.weight.x * d + s.weight.y;
    if (value < best || (value == best && s.info.x < id)) {
      best = value;
      id = s.info.x;
    }
  }
  for (uint k = offsets[at + 2u]; k < offsets[at + 5u]; ++k) {
    uvec2 piece = pieces[k];
    Site s = sites[piece.x];
    d = 3.0e38;
    visit(segments[s.info.y + piece.y]);
    if (d > s.weight.z) continue;
    float value = s.weight.x * d + s.weight.y;
    if (value < best || (value == best && s.info.x < id)) {
      best = value;
      id = s.info.x;
    }
  }
  uint i = px.y * u_size.x + px.x;
  ids[i] = id;
  values[i] = id == 0u ? u_none : best;
}

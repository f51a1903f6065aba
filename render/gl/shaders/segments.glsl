// The distance from p to a site's segments and its side, shared by exact.frag and
// nearest.comp (Compile puts this file where a shader says #include "segments.glsl"): set
// d = 3.0e38 and winding = 0, then visit each segment (a, b) of the site. d becomes the
// least distance from p to them (a point is a segment of length 0), and winding their
// winding number around p (a ray towards +x crossed upwards counts 1, downwards -1).
vec2 p;
float d;
int winding;
void visit(vec4 s) {
  vec2 ab = s.zw - s.xy, ap = p - s.xy;
  float len2 = dot(ab, ab);
  float t = len2 > 0.0 ? clamp(dot(ap, ab) / len2, 0.0, 1.0) : 0.0;
  d = min(d, length(ap - t * ab));
  if ((s.y > p.y) != (s.w > p.y) && p.x < s.x + (p.y - s.y) / (s.w - s.y) * (s.z - s.x)) {
    winding += s.w > s.y ? 1 : -1;
  }
}
// Whether a site whose info.w is `side` (bits 0-1: 0 both sides, 1 outside, 2 inside; bit 2:
// the nonzero rule, else even-odd) is absent at p, from the winding visit left.
bool wrong_side(uint side) {
  bool inside = (side & 4u) != 0u ? winding != 0 : (winding & 1) != 0;
  return (side & 3u) != 0u && d > u_margin && inside != ((side & 3u) == 2u);
}

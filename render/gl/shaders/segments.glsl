// The distance from p to a site's segments and its side, shared by exact.frag and
// nearest.comp (Compile puts this file where a shader says #include "segments.glsl"): set
// d = 3.0e38 and inside = false, then visit each segment (a, b) of the site. d becomes the
// least distance from p to them (a point is a segment of length 0), and inside whether p
// lies inside them by the even-odd rule.
vec2 p;
float d;
bool inside;
void visit(vec4 s) {
  vec2 ab = s.zw - s.xy, ap = p - s.xy;
  float len2 = dot(ab, ab);
  float t = len2 > 0.0 ? clamp(dot(ap, ab) / len2, 0.0, 1.0) : 0.0;
  d = min(d, length(ap - t * ab));
  if ((s.y > p.y) != (s.w > p.y) && p.x < s.x + (p.y - s.y) / (s.w - s.y) * (s.z - s.x)) {
    inside = !inside;
  }
}

// Interlock path (paper §9, Alg. 4-5): each fragment applies its event to its pixel's list in the
// SSBO inside an ordered critical section, so events arrive per pixel in primitive (= visibility)
// order, exactly as the CPU builder applies them. The host's preamble enables the ARB or the NV
// extension (#extension must precede all other tokens) and defines SL_BEGIN_INTERLOCK and
// SL_END_INTERLOCK as its begin/end functions.

layout(pixel_interlock_ordered) in;

layout(std430, binding = 0) readonly buffer SlBoxes {
  SlBox sl_boxes[];
};
layout(std430, binding = 1) readonly buffer SlOrder {
  SlEntry sl_order[];
};
layout(std430, binding = 4) coherent buffer SlCounts {
  uint sl_counts[];
};
layout(std430, binding = 5) coherent buffer SlTSeen {
  float sl_t_seen[];
};
uniform uint u_capacity;
uniform float u_eps;

flat in uint v_entry;

void main() {
  const ivec2 px = ivec2(gl_FragCoord.xy);
  const uint p = uint(px.y - u_row0) * uint(u_width) + uint(px.x);
  const SlEntry en = sl_order[v_entry];
  const SlBox b = sl_boxes[en.box];
  float t;
  const bool hit = sl_box_event_t(sl_pixel_ray(px.x, px.y), b, en.face, t);
  // begin/end must not sit in control flow; misses pass through the critical section doing nothing.
  SL_BEGIN_INTERLOCK();
  if (hit) {
    uint count_word = sl_counts[p];
    float t_seen = sl_t_seen[p];
    if (en.face == SL_FACE_FRONT) {
      sl_add_event(p * u_capacity, count_word, t_seen, u_capacity, t, SL_ENTRY, sl_box_class(b), u_eps);
    } else {
      sl_add_event(p * u_capacity, count_word, t_seen, u_capacity, t, SL_EXIT, sl_box_parent_class(b), u_eps);
    }
    sl_counts[p] = count_word;
    sl_t_seen[p] = t_seen;
  }
  SL_END_INTERLOCK();
}

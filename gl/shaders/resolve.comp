// Fallback pass 2: one invocation per pixel of the band. Gathers the pixel's records, sorts them by
// visibility-order index (restoring the order the interlock path gets from the rasterizer) and
// applies them with sl_add_event, exactly as the CPU builder does (Alg. 4-5). Pixels whose records did
// not all fit (pool or SL_MAX_RECORDS) get a conservative list: one open NON_EMPTY segment from where
// the ray enters the geometry's bounds to the volume exit, flagged as overflowed (as add_event does).

layout(local_size_x = 64) in;

layout(std430, binding = 0) readonly buffer SlBoxes {
  SlBox sl_boxes[];
};
layout(std430, binding = 1) readonly buffer SlOrder {
  SlEntry sl_order[];
};
layout(std430, binding = 4) buffer SlCounts {
  uint sl_counts[];
};
layout(std430, binding = 6) readonly buffer SlHeads {
  uint sl_heads[];
};
layout(std430, binding = 7) readonly buffer SlRecords {
  SlRecord sl_records[];
};
layout(std430, binding = 8) buffer SlControl {
  uint sl_record_count;
  uint sl_record_capacity;
  uint sl_dropped_pixels;
  uint sl_pad;
};
uniform uint u_capacity;
uniform float u_eps;
uniform uint u_band_pixels;
uniform vec3 u_bounds_lo;
uniform vec3 u_bounds_hi;

void main() {
  // Dispatched as a 2D grid of 64-wide groups (a band may need more than 65535 groups).
  const uint p = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * 64u + gl_LocalInvocationID.x;
  if (p >= u_band_pixels) return;
  const uint base = p * u_capacity;
  bool dropped = (sl_counts[p] & 0x80000000u) != 0u;
  uvec2 rec[SL_MAX_RECORDS];  // (entry index, t bits)
  uint n = 0u;
  for (uint i = sl_heads[p]; i != SL_NIL && !dropped; i = sl_records[i].next) {
    if (n == uint(SL_MAX_RECORDS)) {
      dropped = true;
    } else {
      rec[n++] = uvec2(sl_records[i].entry, floatBitsToUint(sl_records[i].t));
    }
  }
  if (dropped) {
    atomicAdd(sl_dropped_pixels, 1u);
    const int x = int(p % uint(u_width));
    const int y = int(p / uint(u_width)) + u_row0;
    const vec2 iv = sl_intersect(sl_pixel_ray(x, y), u_bounds_lo, u_bounds_hi);
    uint count_word = SL_LIST_OVERFLOW;
    if (iv.x < iv.y && iv.y > 0.0) {
      sl_events[base] = sl_make_event(iv.x > 0.0 ? iv.x : 0.0, SL_ENTRY, SL_NONEMPTY);
      count_word |= 1u;
    }
    sl_counts[p] = count_word;
    return;
  }
  // The list is last-in first-out; when fragments arrived in order (llvmpipe keeps primitive order
  // within a tile) reversing makes it sorted and the insertion sort below linear. Any order is sorted.
  for (uint i = 0u; i < n / 2u; ++i) {
    const uvec2 s = rec[i];
    rec[i] = rec[n - 1u - i];
    rec[n - 1u - i] = s;
  }
  for (uint i = 1u; i < n; ++i) {
    const uvec2 key = rec[i];
    uint j = i;
    while (j > 0u && rec[j - 1u].x > key.x) {
      rec[j] = rec[j - 1u];
      --j;
    }
    rec[j] = key;
  }
  uint count_word = 0u;
  float t_seen = uintBitsToFloat(0xFF7FFFFFu);  // kNoEventYet
  for (uint k = 0u; k < n; ++k) {
    const SlEntry en = sl_order[rec[k].x];
    const SlBox b = sl_boxes[en.box];
    const float t = uintBitsToFloat(rec[k].y);
    if (en.face == SL_FACE_FRONT) {
      sl_add_event(base, count_word, t_seen, u_capacity, t, SL_ENTRY, sl_box_class(b), u_eps);
    } else {
      sl_add_event(base, count_word, t_seen, u_capacity, t, SL_EXIT, sl_box_parent_class(b), u_eps);
    }
  }
  sl_counts[p] = count_word;
}

// Fallback pass 1 (no interlock, e.g. Mesa llvmpipe): fragments of different primitives may run in
// any order, so each hit only appends a record (entry index, t) to its pixel's linked list in a global
// pool; resolve.comp then orders each pixel's records by entry index and applies Alg. 5. The hit test
// and t are those of the interlock path (sl_box_event_t), so both paths see the same events.

layout(std430, binding = 0) readonly buffer SlBoxes {
  SlBox sl_boxes[];
};
layout(std430, binding = 1) readonly buffer SlOrder {
  SlEntry sl_order[];
};
// Per pixel: bit 31 set when one of its records did not fit the pool (the resolve then makes the
// list conservative). The resolve overwrites it with the list's count word.
layout(std430, binding = 4) buffer SlCounts {
  uint sl_counts[];
};
layout(std430, binding = 6) buffer SlHeads {
  uint sl_heads[];
};
layout(std430, binding = 7) writeonly buffer SlRecords {
  SlRecord sl_records[];
};
layout(std430, binding = 8) buffer SlControl {
  uint sl_record_count;     // records requested (may exceed the capacity: then the band is redone)
  uint sl_record_capacity;  // records the pool holds
  uint sl_dropped_pixels;   // resolve: pixels made conservative
  uint sl_pad;
};

flat in uint v_entry;

void main() {
  const ivec2 px = ivec2(gl_FragCoord.xy);
  const uint p = uint(px.y - u_row0) * uint(u_width) + uint(px.x);
  const SlEntry en = sl_order[v_entry];
  float t;
  if (!sl_box_event_t(sl_pixel_ray(px.x, px.y), sl_boxes[en.box], en.face, t)) discard;
  const uint i = atomicAdd(sl_record_count, 1u);
  if (i >= sl_record_capacity) {
    atomicOr(sl_counts[p], 0x80000000u);
    return;
  }
  sl_records[i].entry = v_entry;
  sl_records[i].t = t;
  sl_records[i].next = atomicExchange(sl_heads[p], i);
}

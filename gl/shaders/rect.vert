// One rectangle per visibility-order entry (DESIGN.md "Ray segment lists"): vertices 6k..6k+5 draw draw-slot k as two
// triangles sharing a diagonal, covering exactly the pixel centres of the entry's box's
// conservative_screen_rect (computed on the host by the CPU builder's function). GL's fill rule gives
// every covered pixel centre exactly one fragment, and primitive order is draw-slot order.

layout(std430, binding = 1) readonly buffer SlOrder {
  SlEntry sl_order[];
};
// Inclusive pixel rectangle per box (x0, y0, x1, y1); empty when x0 > x1.
layout(std430, binding = 2) readonly buffer SlRects {
  ivec4 sl_rects[];
};
// Test hook for the fallback: draw slot -> entry index (a permutation), so fragments arrive scrambled.
layout(std430, binding = 9) readonly buffer SlDrawOrder {
  uint sl_draw_order[];
};
uniform int u_use_draw_order;

flat out uint v_entry;

void main() {
  const uint slot = uint(gl_VertexID) / 6u;
  const uint corner = uint(gl_VertexID) % 6u;
  const uint entry = u_use_draw_order != 0 ? sl_draw_order[slot] : slot;
  const ivec4 r = sl_rects[sl_order[entry].box];
  v_entry = entry;
  if (r.x > r.z || r.y > r.w) {
    gl_Position = vec4(2.0, 2.0, 2.0, 1.0);  // all six vertices coincide: nothing is rasterized
    return;
  }
  // Corners (0,0) (1,0) (1,1) / (0,0) (1,1) (0,1); pixel edges, so pixel centres lie strictly inside.
  const bool right = corner == 1u || corner == 2u || corner == 4u;
  const bool top = corner == 2u || corner == 4u || corner == 5u;
  const float x = float(right ? r.z + 1 : r.x);
  const float y = float(top ? r.w + 1 : r.y);
  gl_Position = vec4(2.0 * x / float(u_width) - 1.0, 2.0 * y / float(u_height) - 1.0, 0.0, 1.0);
}

// Shared declarations of the GL segment-list builder: the std430 mirrors of the C++ structs, the
// per-frame uniforms, the pixel's ray (RayGenerator::ray) and the slab test (intersect in core/util/ray.h).
// The ray and the slab test repeat the C++ float operations one for one and in the same order, and
// `precise` forbids the compiler to contract or reassociate them (no fma, no a*rcp(b) for a/b), so a
// pixel's hit decision and its t equal the CPU builder's bit for bit (DESIGN.md "Ray segment lists").

// sl::RayEvent (8 bytes): float t; then bytes type (bits 0-7), cls (bits 8-15), pad (16-31 = 0).
struct SlRayEvent {
  float t;
  uint bits;
};

// sl::OccupancyBox (32 bytes). std430 would pad a vec3 to 16 bytes, so the box is read as six floats;
// cls is byte 24, parent_cls byte 25, depth byte 26, pad byte 27, node bytes 28-31.
struct SlBox {
  float lo_x, lo_y, lo_z;
  float hi_x, hi_y, hi_z;
  uint classes;
  uint node;
};

// sl::VisibilityEntry (8 bytes): box index, face (0 = FRONT, 1 = BACK).
struct SlEntry {
  uint box;
  uint face;
};

// Fallback record: the visibility-order index of the entry that produced it, the event depth, and the
// next record of the same pixel (per-pixel linked list in a global pool, 12 bytes).
struct SlRecord {
  uint entry;
  float t;
  uint next;
};

const uint SL_ENTRY = 0u;
const uint SL_EXIT = 1u;
const uint SL_EMPTY = 0u;
const uint SL_NONEMPTY = 1u;
const uint SL_UNKNOWN = 2u;
const uint SL_INVALID = 3u;
const uint SL_FACE_FRONT = 0u;
const uint SL_NIL = 0xFFFFFFFFu;

// RayGenerator (core/scene/camera.h), as uploaded: the exact float values of the C++ struct.
uniform vec3 u_eye;
uniform vec3 u_forward;
uniform vec3 u_right;
uniform vec3 u_up;
uniform float u_half_h;
uniform float u_aspect;
uniform int u_width;
uniform int u_height;
uniform int u_orthographic;
// The band of image rows being built: pixel (x, y) is list (y - u_row0) * u_width + x of the band.
uniform int u_row0;

uint sl_box_class(SlBox b) { return b.classes & 0xFFu; }
uint sl_box_parent_class(SlBox b) { return (b.classes >> 8) & 0xFFu; }
vec3 sl_box_lo(SlBox b) { return vec3(b.lo_x, b.lo_y, b.lo_z); }
vec3 sl_box_hi(SlBox b) { return vec3(b.hi_x, b.hi_y, b.hi_z); }

struct SlRay {
  vec3 origin;
  vec3 dir;
};

// RayGenerator::ray(x, y), operation for operation.
SlRay sl_pixel_ray(int x, int y) {
  precise float sx = (2.0 * (float(x) + 0.5) / float(u_width) - 1.0) * u_half_h * u_aspect;
  precise float sy = (1.0 - 2.0 * (float(y) + 0.5) / float(u_height)) * u_half_h;
  SlRay r;
  if (u_orthographic != 0) {
    precise vec3 origin = (u_eye + sx * u_right) + sy * u_up;  // eye + sx * right + sy * up
    r.origin = origin;
    r.dir = u_forward;
  } else {
    precise vec3 d = (u_forward + sx * u_right) + sy * u_up;
    // glm::normalize(d) = d * inversesqrt(dot(d, d)); GLM's dot is (x*x + y*y) + z*z and its
    // inversesqrt is 1 / sqrt. GLSL's normalize() would be free to use another order or rsq.
    precise float dd = (d.x * d.x + d.y * d.y) + d.z * d.z;
    precise float inv_len = 1.0 / sqrt(dd);
    precise vec3 dir = d * inv_len;
    r.origin = u_eye;
    r.dir = dir;
  }
  return r;
}

// sl::intersect (core/util/ray.h), the slab test every builder uses. Returns (t0, t1); a miss has
// !(t0 < t1). An axis with dir == 0 hits only if the origin lies within the slab there.
vec2 sl_intersect(SlRay r, vec3 lo, vec3 hi) {
  precise float t0 = uintBitsToFloat(0xFF7FFFFFu);  // -3.402823466e+38f
  precise float t1 = uintBitsToFloat(0x7F7FFFFFu);  // 3.402823466e+38f
  for (int a = 0; a < 3; ++a) {
    const float o = r.origin[a];
    const float d = r.dir[a];
    if (d == 0.0) {
      if (o < lo[a] || o > hi[a]) return vec2(1.0, 0.0);
      continue;
    }
    precise float inv = 1.0 / d;
    precise float u = (lo[a] - o) * inv;
    precise float v = (hi[a] - o) * inv;
    if (u > v) {
      const float s = u;
      u = v;
      v = s;
    }
    t0 = u > t0 ? u : t0;
    t1 = v < t1 ? v : t1;
  }
  return vec2(t0, t1);
}

// Alg. 4 for one box and one ray, as add_box_event decides it: a miss (t0 >= t1, grazing included)
// or a box wholly behind the origin (t1 <= 0) adds nothing; FRONT enters at max(t0, 0), BACK exits at
// t1. Returns false when nothing is added.
bool sl_box_event_t(SlRay r, SlBox b, uint face, out float t) {
  const vec2 iv = sl_intersect(r, sl_box_lo(b), sl_box_hi(b));
  t = 0.0;
  if (!(iv.x < iv.y) || !(iv.y > 0.0)) return false;
  t = face == SL_FACE_FRONT ? (iv.x > 0.0 ? iv.x : 0.0) : iv.y;
  return true;
}

// What crosses between C++ and GLSL (STYLE.md #3): the std430 view of OccupancyBox, VisibilityEntry,
// RayEvent and the fallback record matches the C++ structs byte for byte, read and written on the GL
// side by the very declarations the builder compiles (gl/shaders/common.glsl, segment_list.glsl); and
// the GLSL add_event (Alg. 5) mirrors core/lists/segment_list.h on random event streams, including equal
// depths, out-of-order depths, the short-gap rule and overflow.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <vector>

#include "core/lists/segment_list.h"
#include "gl/gl_program.h"
#include "tests/gl/gl_test_util.h"

namespace sl {
namespace {

struct CpuRecord {  // what SlRecord must be: 12 bytes, array stride 12
  std::uint32_t entry;
  float t;
  std::uint32_t next;
};
static_assert(sizeof(CpuRecord) == 12);

constexpr const char* kLayoutMain = R"glsl(
layout(local_size_x = 1) in;
layout(std430, binding = 0) readonly buffer InBoxes { SlBox in_boxes[]; };
layout(std430, binding = 1) readonly buffer InOrder { SlEntry in_order[]; };
layout(std430, binding = 10) writeonly buffer OutWords { uint out_words[]; };
layout(std430, binding = 11) readonly buffer InEvents { SlRayEvent in_events[]; };
layout(std430, binding = 12) writeonly buffer OutRecords { SlRecord out_records[]; };
uniform uint u_n;
void main() {
  for (uint i = 0u; i < u_n; ++i) {
    const SlBox b = in_boxes[i];
    const uint o = i * 16u;
    out_words[o + 0u] = floatBitsToUint(sl_box_lo(b).x);
    out_words[o + 1u] = floatBitsToUint(sl_box_lo(b).y);
    out_words[o + 2u] = floatBitsToUint(sl_box_lo(b).z);
    out_words[o + 3u] = floatBitsToUint(sl_box_hi(b).x);
    out_words[o + 4u] = floatBitsToUint(sl_box_hi(b).y);
    out_words[o + 5u] = floatBitsToUint(sl_box_hi(b).z);
    out_words[o + 6u] = sl_box_class(b);
    out_words[o + 7u] = sl_box_parent_class(b);
    out_words[o + 8u] = (b.classes >> 16) & 0xFFu;  // depth
    out_words[o + 9u] = b.node;
    out_words[o + 10u] = in_order[i].box;
    out_words[o + 11u] = in_order[i].face;
    out_words[o + 12u] = floatBitsToUint(in_events[i].t);
    out_words[o + 13u] = sl_event_type(in_events[i]);
    out_words[o + 14u] = sl_event_class(in_events[i]);
    out_words[o + 15u] = 0xC0FFEEu;
    sl_events[i] = sl_make_event(float(i) * 1.25 + 0.5, i & 1u, i % 4u);
    out_records[i] = SlRecord(i * 3u + 1u, float(i) - 0.75, 0xABC00000u + i);
  }
}
)glsl";

TEST(GlLayout, Std430ViewMatchesTheCppStructs) {
  SL_REQUIRE_GL(ctx);
  constexpr std::uint32_t n = 5;
  std::vector<OccupancyBox> boxes(n);
  std::vector<VisibilityEntry> order(n);
  std::vector<RayEvent> events(n);
  for (std::uint32_t i = 0; i < n; ++i) {
    boxes[i].box = Box3{vec3(1.5f + i, -2.25f * i, 3.0f), vec3(7.0f, 8.5f + i, 1e30f)};
    boxes[i].cls = OccupancyClass(i % 3);
    boxes[i].parent_cls = OccupancyClass((i + 1) % 4);
    boxes[i].depth = std::uint8_t(7 + i);
    boxes[i].pad = 0xEE;  // must not leak into the classes the shader reads
    boxes[i].node = 123456u + i;
    order[i] = VisibilityEntry{1000u + i, i % 2 ? Face::Back : Face::Front};
    events[i] = detail::make_event(-3.5f + 2.0f * i, EventType(i % 2), OccupancyClass((i + 2) % 4));
  }
  GlBuffer b_boxes, b_order, b_events_in, b_words, b_events_out, b_records;
  b_boxes.upload(boxes.data(), n * sizeof(OccupancyBox));
  b_order.upload(order.data(), n * sizeof(VisibilityEntry));
  b_events_in.upload(events.data(), n * sizeof(RayEvent));
  b_words.allocate(n * 16 * 4);
  b_events_out.allocate(n * sizeof(RayEvent));
  b_records.allocate(n * sizeof(CpuRecord));
  b_boxes.bind(0);
  b_order.bind(1);
  b_events_out.bind(3);
  b_words.bind(10);
  b_events_in.bind(11);
  b_records.bind(12);
  GlProgram prog("layout probe",
                 {{GL_COMPUTE_SHADER, assemble_glsl("", {"common.glsl", "segment_list.glsl"}) + kLayoutMain}});
  glProgramUniform1ui(prog.id(), prog.uniform("u_n"), n);
  glUseProgram(prog.id());
  glDispatchCompute(1, 1, 1);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  std::vector<std::uint32_t> words(n * 16);
  std::vector<RayEvent> written(n);
  std::vector<CpuRecord> records(n);
  b_words.read(0, words.size() * 4, words.data());
  b_events_out.read(0, n * sizeof(RayEvent), written.data());
  b_records.read(0, n * sizeof(CpuRecord), records.data());
  gl_check("layout probe");
  auto bits = [](float f) {
    std::uint32_t u;
    std::memcpy(&u, &f, 4);
    return u;
  };
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint32_t* w = &words[i * 16];
    EXPECT_EQ(w[0], bits(boxes[i].box.lo.x));
    EXPECT_EQ(w[1], bits(boxes[i].box.lo.y));
    EXPECT_EQ(w[2], bits(boxes[i].box.lo.z));
    EXPECT_EQ(w[3], bits(boxes[i].box.hi.x));
    EXPECT_EQ(w[4], bits(boxes[i].box.hi.y));
    EXPECT_EQ(w[5], bits(boxes[i].box.hi.z));
    EXPECT_EQ(w[6], std::uint32_t(boxes[i].cls));
    EXPECT_EQ(w[7], std::uint32_t(boxes[i].parent_cls));
    EXPECT_EQ(w[8], std::uint32_t(boxes[i].depth));
    EXPECT_EQ(w[9], boxes[i].node);
    EXPECT_EQ(w[10], order[i].box);
    EXPECT_EQ(w[11], std::uint32_t(order[i].face));
    EXPECT_EQ(w[12], bits(events[i].t));
    EXPECT_EQ(w[13], std::uint32_t(events[i].type));
    EXPECT_EQ(w[14], std::uint32_t(events[i].cls));
    EXPECT_EQ(w[15], 0xC0FFEEu);
    EXPECT_EQ(written[i].t, float(i) * 1.25f + 0.5f);
    EXPECT_EQ(written[i].type, i & 1u);
    EXPECT_EQ(written[i].cls, i % 4u);
    EXPECT_EQ(written[i].pad, 0u);
    EXPECT_EQ(records[i].entry, i * 3u + 1u);
    EXPECT_EQ(records[i].t, float(i) - 0.75f);
    EXPECT_EQ(records[i].next, 0xABC00000u + i);
  }
}

constexpr const char* kAddEventMain = R"glsl(
layout(local_size_x = 64) in;
// Per list: first input event, number of input events, capacity, eps (bits).
layout(std430, binding = 10) readonly buffer Headers { uvec4 headers[]; };
layout(std430, binding = 11) readonly buffer Inputs { SlRayEvent inputs[]; };
layout(std430, binding = 12) writeonly buffer Results { uvec2 results[]; };  // count word, t_seen bits
uniform uint u_lists;
void main() {
  const uint l = gl_GlobalInvocationID.x;
  if (l >= u_lists) return;
  const uvec4 h = headers[l];
  uint count_word = 0u;
  float t_seen = uintBitsToFloat(0xFF7FFFFFu);
  for (uint k = 0u; k < h.y; ++k) {
    const SlRayEvent e = inputs[h.x + k];
    sl_add_event(l * 64u, count_word, t_seen, h.z, e.t, sl_event_type(e), sl_event_class(e), uintBitsToFloat(h.w));
  }
  results[l] = uvec2(count_word, floatBitsToUint(t_seen));
}
)glsl";

TEST(GlLayout, GlslAddEventMirrorsCoreOnRandomStreams) {
  SL_REQUIRE_GL(ctx);
  static_assert(kMaxEvents == 64, "the shader above lays lists out 64 events apart");
  constexpr std::uint32_t lists = 6000;
  std::mt19937 rng(99);
  auto uni = [&](int n) { return int(rng() % std::uint32_t(n)); };
  const float eps_choices[] = {0.0f, 0.0f, 0.3f, 1.0f};
  std::vector<std::uint32_t> headers;
  std::vector<RayEvent> inputs;
  for (std::uint32_t l = 0; l < lists; ++l) {
    const std::uint32_t first = std::uint32_t(inputs.size());
    const int m = uni(49);
    const std::uint32_t capacity = uni(4) == 0 ? kMaxEvents : std::uint32_t(2 + uni(10));
    const float eps = eps_choices[uni(4)];
    float t = float(uni(8)) * 0.25f;
    for (int k = 0; k < m; ++k) {
      const int r = uni(20);
      if (r < 3) {
        t -= 0.25f * float(1 + uni(2));  // out of order: the t_seen guard
      } else if (r < 10) {
        t += 0.125f * float(1 + uni(6));  // else: same depth, the Alg. 5 same-depth rules
      }
      inputs.push_back(detail::make_event(t, EventType(uni(2)), OccupancyClass(uni(4))));
    }
    std::uint32_t eps_bits;
    std::memcpy(&eps_bits, &eps, 4);
    headers.insert(headers.end(), {first, std::uint32_t(m), capacity, eps_bits});
  }
  GlBuffer b_headers, b_inputs, b_results, b_events;
  b_headers.upload(headers.data(), headers.size() * 4);
  b_inputs.upload(inputs.data(), inputs.size() * sizeof(RayEvent));
  b_results.allocate(lists * 8);
  b_events.allocate(std::size_t(lists) * kMaxEvents * sizeof(RayEvent));
  b_events.bind(3);
  b_headers.bind(10);
  b_inputs.bind(11);
  b_results.bind(12);
  GlProgram prog("add_event mirror",
                 {{GL_COMPUTE_SHADER, assemble_glsl("", {"common.glsl", "segment_list.glsl"}) + kAddEventMain}});
  glProgramUniform1ui(prog.id(), prog.uniform("u_lists"), lists);
  glUseProgram(prog.id());
  glDispatchCompute((lists + 63) / 64, 1, 1);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  std::vector<std::uint32_t> results(lists * 2);
  std::vector<RayEvent> gl_events(std::size_t(lists) * kMaxEvents);
  b_results.read(0, results.size() * 4, results.data());
  b_events.read(0, gl_events.size() * sizeof(RayEvent), gl_events.data());
  gl_check("add_event mirror");

  std::size_t differing = 0, overflowed = 0, merged = 0;
  for (std::uint32_t l = 0; l < lists; ++l) {
    const std::uint32_t* h = &headers[l * 4];
    float eps;
    std::memcpy(&eps, &h[3], 4);
    RayEvent ev[kMaxEvents];
    std::uint32_t count_word = 0;
    float t_seen = kNoEventYet;
    for (std::uint32_t k = 0; k < h[1]; ++k) {
      const RayEvent& e = inputs[h[0] + k];
      add_event(ev, count_word, t_seen, h[2], e.t, EventType(e.type), OccupancyClass(e.cls), eps);
    }
    float gl_t_seen;
    std::memcpy(&gl_t_seen, &results[l * 2 + 1], 4);
    bool same = results[l * 2] == count_word && gl_t_seen == t_seen;
    for (std::uint32_t k = 0; same && k < (count_word & kListCountMask); ++k) {
      same = std::memcmp(&ev[k], &gl_events[std::size_t(l) * kMaxEvents + k], sizeof(RayEvent)) == 0;
    }
    differing += same ? 0 : 1;
    overflowed += (count_word & kListOverflow) ? 1 : 0;
    merged += (count_word & kListCountMask) < h[1] ? 1 : 0;
  }
  EXPECT_EQ(differing, 0u);
  EXPECT_GT(overflowed, lists / 20);  // the streams exercise overflow...
  EXPECT_GT(merged, lists / 2);       // ...and the merge rules
}

}  // namespace
}  // namespace sl

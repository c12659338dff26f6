#include "gl/gl_segment_list_builder.h"

#include <algorithm>
#include <cstring>
#include <numeric>

#include "core/util/parallel.h"
#include "core/frame/stats.h"
#include "gl/gl_program.h"

namespace sl {

static_assert(sizeof(ScreenRect) == 16, "ScreenRect is uploaded as ivec4");
static_assert(sizeof(RayEvent) == 8 && sizeof(OccupancyBox) == 32 && sizeof(VisibilityEntry) == 8,
              "layouts mirrored by gl/shaders/common.glsl");

const char* to_string(GlListPath path) { return path == GlListPath::Interlock ? "interlock" : "fallback"; }

namespace {

// Shader-storage bindings (gl/shaders/*).
enum Binding : GLuint {
  kBoxes = 0, kOrder = 1, kRects = 2, kEvents = 3, kCounts = 4, kTSeen = 5, kHeads = 6, kRecords = 7,
  kControl = 8, kDrawOrder = 9
};

constexpr std::size_t kRecordBytes = 12;  // SlRecord: entry, t, next
constexpr std::uint32_t kNoEventYetBits = 0xFF7FFFFFu;  // kNoEventYet (-FLT_MAX)

struct Control {  // SlControl
  std::uint32_t record_count = 0;
  std::uint32_t record_capacity = 0;
  std::uint32_t dropped_pixels = 0;
  std::uint32_t pad = 0;
};

void set_camera_uniforms(GLuint prog, const GlProgram& p, const RayGenerator& g) {
  glProgramUniform3f(prog, p.uniform("u_eye"), g.eye.x, g.eye.y, g.eye.z);
  glProgramUniform3f(prog, p.uniform("u_forward"), g.forward.x, g.forward.y, g.forward.z);
  glProgramUniform3f(prog, p.uniform("u_right"), g.right.x, g.right.y, g.right.z);
  glProgramUniform3f(prog, p.uniform("u_up"), g.up.x, g.up.y, g.up.z);
  glProgramUniform1f(prog, p.uniform("u_half_h"), g.half_h);
  glProgramUniform1f(prog, p.uniform("u_aspect"), g.aspect);
  glProgramUniform1i(prog, p.uniform("u_width"), g.width);
  glProgramUniform1i(prog, p.uniform("u_height"), g.height);
  glProgramUniform1i(prog, p.uniform("u_orthographic"), g.orthographic ? 1 : 0);
}

}  // namespace

struct GlSegmentListBuilder::Impl {
  GlContext& context;
  GlBuilderOptions options;
  std::size_t max_block = 0;    // GL_MAX_SHADER_STORAGE_BLOCK_SIZE
  GlProgram raster;             // rect.vert + interlock.frag or append.frag
  GlProgram resolve;            // fallback only
  GlDrawTarget target;
  GlBuffer boxes, order, rects, draw_order, events, counts, t_seen, heads, records, control;
  bool use_draw_order = false;
  std::size_t pool_records = 0;  // fallback pool size, kept between builds
  int width = 0, height = 0;
  std::uint32_t capacity = 0;
  std::uint32_t entries = 0;
  GLint max_fb_width = 0, max_fb_height = 0;  // GL_MAX_FRAMEBUFFER_WIDTH / HEIGHT

  Impl(GlContext& c, GlBuilderOptions o) : context(c), options(o) {}

  // Draws all entries over rows [row0, row0 + rows) (scissored), after clearing that band's state.
  void draw_band(int row0, int rows, bool fallback) {
    const std::size_t px0 = std::size_t(row0) * std::size_t(width);
    const std::size_t npx = std::size_t(rows) * std::size_t(width);
    counts.clear_u32(px0 * 4, npx * 4, 0u);
    counts.bind_range(kCounts, px0 * 4, npx * 4);
    events.bind_range(kEvents, px0 * capacity * sizeof(RayEvent), npx * capacity * sizeof(RayEvent));
    if (fallback) {
      heads.clear_u32(0, npx * 4, 0xFFFFFFFFu);
      heads.bind_range(kHeads, 0, npx * 4);
      const Control c{0u, std::uint32_t(pool_records), 0u, 0u};
      glNamedBufferSubData(control.id(), 0, sizeof c, &c);
      control.bind(kControl);
      records.bind_range(kRecords, 0, std::max<std::size_t>(pool_records * kRecordBytes, 16));
    } else {
      t_seen.clear_u32(px0 * 4, npx * 4, kNoEventYetBits);
      t_seen.bind_range(kTSeen, px0 * 4, npx * 4);
    }
    glProgramUniform1i(raster.id(), raster.uniform("u_row0"), row0);
    glUseProgram(raster.id());
    glEnable(GL_SCISSOR_TEST);
    glScissor(0, row0, width, rows);
    if (entries > 0) glDrawArrays(GL_TRIANGLES, 0, GLsizei(6u * entries));
    glDisable(GL_SCISSOR_TEST);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
  }

  void resolve_band(int row0, int rows) {
    const std::uint32_t npx = std::uint32_t(rows) * std::uint32_t(width);
    glProgramUniform1i(resolve.id(), resolve.uniform("u_row0"), row0);
    glProgramUniform1ui(resolve.id(), resolve.uniform("u_band_pixels"), npx);
    glUseProgram(resolve.id());
    const std::uint32_t groups = (npx + 63u) / 64u;
    const std::uint32_t gx = std::min<std::uint32_t>(groups, 65535u);
    glDispatchCompute(gx, (groups + gx - 1u) / gx, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
  }

  Control read_control() const {
    Control c;
    control.read(0, sizeof c, &c);
    return c;
  }
};

GlSegmentListBuilder::GlSegmentListBuilder(GlContext& context, GlBuilderOptions options)
    : impl_(std::make_unique<Impl>(context, options)) {
  Impl& m = *impl_;
  context.make_current();
  const GlInfo& info = context.info();
  const bool want_interlock = options.path != GlBuilderOptions::Path::Fallback && info.interlock();
  if (options.path == GlBuilderOptions::Path::Interlock && !info.interlock()) {
    throw GlError("the interlock path needs GL_ARB_fragment_shader_interlock or GL_NV_fragment_shader_interlock, "
                  "which '" + info.renderer + "' lacks");
  }
  path_ = want_interlock ? GlListPath::Interlock : GlListPath::Fallback;
  SL_CHECK(options.max_records_per_pixel >= 1u);

  GLint64 max_block = 0;
  glGetInteger64v(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &max_block);
  m.max_block = std::size_t(max_block > 0 ? max_block : (1 << 27));
  glGetIntegerv(GL_MAX_FRAMEBUFFER_WIDTH, &m.max_fb_width);
  glGetIntegerv(GL_MAX_FRAMEBUFFER_HEIGHT, &m.max_fb_height);

  const std::string vert = assemble_glsl("", {"common.glsl", "rect.vert"});
  if (path_ == GlListPath::Interlock) {
    const std::string pre =
        info.arb_interlock
            ? "#extension GL_ARB_fragment_shader_interlock : require\n#define SL_EVENTS_QUALIFIER coherent\n"
              "#define SL_BEGIN_INTERLOCK beginInvocationInterlockARB\n#define SL_END_INTERLOCK endInvocationInterlockARB\n"
            : "#extension GL_NV_fragment_shader_interlock : require\n#define SL_EVENTS_QUALIFIER coherent\n"
              "#define SL_BEGIN_INTERLOCK beginInvocationInterlockNV\n#define SL_END_INTERLOCK endInvocationInterlockNV\n";
    m.raster = GlProgram("segment-list interlock program",
                         {{GL_VERTEX_SHADER, vert},
                          {GL_FRAGMENT_SHADER, assemble_glsl(pre, {"common.glsl", "segment_list.glsl", "interlock.frag"})}});
  } else {
    m.raster = GlProgram("segment-list append program",
                         {{GL_VERTEX_SHADER, vert},
                          {GL_FRAGMENT_SHADER, assemble_glsl("", {"common.glsl", "append.frag"})}});
    const std::string pre = "#define SL_MAX_RECORDS " + std::to_string(options.max_records_per_pixel) + "\n";
    m.resolve = GlProgram("segment-list resolve program",
                          {{GL_COMPUTE_SHADER, assemble_glsl(pre, {"common.glsl", "segment_list.glsl", "resolve.comp"})}});
  }
  m.control.allocate(sizeof(Control));
  gl_check("GlSegmentListBuilder setup");
}

GlSegmentListBuilder::~GlSegmentListBuilder() = default;

void GlSegmentListBuilder::set_draw_order_for_testing(std::vector<std::uint32_t> draw_order) {
  SL_CHECK(draw_order.empty() || path_ == GlListPath::Fallback);  // interlock relies on draw order
  impl_->use_draw_order = !draw_order.empty();
  impl_->draw_order.upload(draw_order.data(), draw_order.size() * 4);
}

GlBuildStats GlSegmentListBuilder::build(const OccupancyGeometry& geometry, std::span<const VisibilityEntry> order,
                                         const RayGenerator& gen, std::uint32_t capacity, float eps) {
  Impl& m = *impl_;
  SL_CHECK(capacity >= 2u && capacity <= kMaxEvents);
  SL_CHECK(gen.width > 0 && gen.height > 0);
  if (gen.width > impl_->max_fb_width || gen.height > impl_->max_fb_height) {
    throw GlError("image " + std::to_string(gen.width) + "x" + std::to_string(gen.height) + " exceeds the largest " +
                  "framebuffer (" + std::to_string(impl_->max_fb_width) + "x" + std::to_string(impl_->max_fb_height) + ")");
  }
  const bool fallback = path_ == GlListPath::Fallback;
  m.context.make_current();
  GlBuildStats st;
  st.path = path_;
  const Timer total;
  Timer t;

  // Upload: boxes as raw OccupancyBox bytes (the shader reads them as floats), the order, and each
  // box's conservative_screen_rect — the CPU builder's rectangle, computed by the same function.
  m.width = gen.width;
  m.height = gen.height;
  m.capacity = capacity;
  m.entries = std::uint32_t(order.size());
  for (const VisibilityEntry& e : order) SL_CHECK(e.box < geometry.boxes.size());
  if (m.use_draw_order) SL_CHECK(m.draw_order.bytes() >= std::max<std::size_t>(order.size() * 4, 16));
  std::vector<ScreenRect> rects(geometry.boxes.size());
  parallel_for(std::size_t(0), rects.size(),
               [&](std::size_t i) { rects[i] = conservative_screen_rect(geometry.boxes[i].box, gen); });
  Box3 bounds{vec3(3.4e38f), vec3(-3.4e38f)};
  for (const OccupancyBox& b : geometry.boxes) {
    bounds.lo = glm::min(bounds.lo, b.box.lo);
    bounds.hi = glm::max(bounds.hi, b.box.hi);
  }
  m.boxes.upload(geometry.boxes.data(), geometry.boxes.size() * sizeof(OccupancyBox));
  m.order.upload(order.data(), order.size() * sizeof(VisibilityEntry));
  m.rects.upload(rects.data(), rects.size() * sizeof(ScreenRect));
  const std::size_t pixels = std::size_t(gen.width) * std::size_t(gen.height);
  m.events.allocate(pixels * capacity * sizeof(RayEvent));
  m.counts.allocate(pixels * 4);
  m.boxes.bind(kBoxes);
  m.order.bind(kOrder);
  m.rects.bind(kRects);
  if (m.use_draw_order) {
    m.draw_order.bind(kDrawOrder);
  } else {
    m.order.bind(kDrawOrder);  // unread, but every declared block gets a buffer
  }
  for (const GlProgram* p : {&m.raster, &m.resolve}) {
    if (!p->id()) continue;
    set_camera_uniforms(p->id(), *p, gen);
    glProgramUniform1ui(p->id(), p->uniform("u_capacity"), capacity);
    glProgramUniform1f(p->id(), p->uniform("u_eps"), eps);
    glProgramUniform1i(p->id(), p->uniform("u_use_draw_order"), m.use_draw_order ? 1 : 0);
    glProgramUniform3f(p->id(), p->uniform("u_bounds_lo"), bounds.lo.x, bounds.lo.y, bounds.lo.z);
    glProgramUniform3f(p->id(), p->uniform("u_bounds_hi"), bounds.hi.x, bounds.hi.y, bounds.hi.z);
  }

  // Bands: a band's lists must fit one storage binding, and a band must start at a row whose
  // count-word offset (row * width * 4 bytes) meets the binding offset alignment.
  GLint align = 16;
  glGetIntegerv(GL_SHADER_STORAGE_BUFFER_OFFSET_ALIGNMENT, &align);
  const std::size_t row_bytes = std::size_t(gen.width) * 4;
  const int row_step = int(std::size_t(std::max(align, 1)) / std::gcd(row_bytes, std::size_t(std::max(align, 1))));
  const std::size_t band_limit =
      m.options.max_band_bytes > 0 ? std::min(m.options.max_band_bytes, m.max_block) : m.max_block;
  const std::size_t list_row_bytes = std::size_t(gen.width) * capacity * sizeof(RayEvent);
  int band_rows = int(std::min<std::size_t>(std::size_t(gen.height), band_limit / list_row_bytes));
  band_rows = std::max(row_step, band_rows / row_step * row_step);
  if (std::size_t(band_rows) * list_row_bytes > m.max_block) {
    throw GlError("image rows too wide for one storage block: " + std::to_string(list_row_bytes) + " bytes per row");
  }
  if (fallback) {
    m.heads.reserve(std::size_t(band_rows) * row_bytes);
    // First guess for the pool: 16 records per pixel of a band; it grows to what a band needed.
    const std::size_t max_pool = std::min(m.options.max_record_bytes, m.max_block) / kRecordBytes;
    m.pool_records = std::min(max_pool, std::max(m.pool_records, std::size_t(band_rows) * gen.width * 16));
    m.records.reserve(m.pool_records * kRecordBytes);
  } else {
    m.t_seen.allocate(pixels * 4);
  }
  glFinish();
  st.upload_ms = t.ms();

  m.target.bind(gen.width, gen.height);
  std::vector<std::pair<int, int>> todo;  // (row0, rows), processed from the back
  for (int r = ((gen.height - 1) / band_rows) * band_rows; r >= 0; r -= band_rows) {
    todo.emplace_back(r, std::min(band_rows, gen.height - r));
  }
  const std::size_t max_pool = std::min(m.options.max_record_bytes, m.max_block) / kRecordBytes;
  while (!todo.empty()) {
    const auto [row0, rows] = todo.back();
    t = Timer();
    m.draw_band(row0, rows, fallback);
    if (!fallback) {
      glFinish();
      st.raster_ms += t.ms();
      ++st.bands;
      todo.pop_back();
      continue;
    }
    const Control c = m.read_control();  // waits for the band's fragments
    st.raster_ms += t.ms();
    if (c.record_count > m.pool_records) {
      if (c.record_count <= max_pool) {  // grow the pool to what the band needs and draw it again
        m.pool_records = std::min(max_pool, std::size_t(c.record_count) + c.record_count / 4);
        m.records.reserve(m.pool_records * kRecordBytes);
        ++st.redraws;
        continue;
      }
      if (rows > row_step) {  // too many even for the largest pool: split the band
        const int half = std::max(row_step, rows / 2 / row_step * row_step);
        todo.pop_back();
        todo.emplace_back(row0 + half, rows - half);
        todo.emplace_back(row0, half);
        ++st.redraws;
        continue;
      }
      // A minimal band that still does not fit: its dropped pixels become conservative in the resolve.
    }
    todo.pop_back();
    ++st.bands;
    st.records += std::min<std::uint64_t>(c.record_count, m.pool_records);
    t = Timer();
    m.resolve_band(row0, rows);
    st.dropped_pixels += m.read_control().dropped_pixels;
    st.resolve_ms += t.ms();
  }
  gl_check("GlSegmentListBuilder::build");
  st.total_ms = total.ms();
  return st;
}

void GlSegmentListBuilder::read_back(SegmentListBuffer& out, GlBuildStats* stats) const {
  const Impl& m = *impl_;
  m.context.make_current();
  const Timer t;
  const std::size_t pixels = std::size_t(m.width) * std::size_t(m.height);
  SL_CHECK(pixels > 0);  // after a build
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_CLIENT_MAPPED_BUFFER_BARRIER_BIT);
  // Mapped rather than copied: only the events the lists hold are read, straight into the compact array.
  const auto* counts = static_cast<const std::uint32_t*>(
      glMapNamedBufferRange(m.counts.id(), 0, GLsizeiptr(pixels * 4), GL_MAP_READ_BIT));
  const auto* events = static_cast<const RayEvent*>(
      glMapNamedBufferRange(m.events.id(), 0, GLsizeiptr(pixels * m.capacity * sizeof(RayEvent)), GL_MAP_READ_BIT));
  SegmentListStats lists;
  if (counts && events) lists = compact_fixed_lists(events, counts, m.capacity, m.width, m.height, out);
  if (counts) glUnmapNamedBuffer(m.counts.id());
  if (events) glUnmapNamedBuffer(m.events.id());
  if (!counts || !events) throw GlError("GlSegmentListBuilder::read_back: cannot map the list buffers");
  gl_check("GlSegmentListBuilder::read_back");
  if (stats) {
    stats->readback_ms = t.ms();
    stats->total_ms += stats->readback_ms;
    stats->lists = lists;
  }
}

GlBuildStats GlSegmentListBuilder::build_segment_lists(const OccupancyGeometry& geometry,
                                                       std::span<const VisibilityEntry> order, const RayGenerator& gen,
                                                       SegmentListBuffer& out, float eps) {
  GlBuildStats st = build(geometry, order, gen, impl_->options.list_capacity, eps);
  read_back(out, &st);
  return st;
}

}  // namespace sl

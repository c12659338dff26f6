#include "apps/bench/bench_run.h"

#include <algorithm>
#include <sstream>

#include "core/util/atomic_file.h"
#include "core/util/error.h"
#if SL_HAVE_MPI
#include "apps/distributed.h"
#endif

namespace sl::app {

std::unique_ptr<SceneRenderer> BenchRun::renderer() const {
  auto r = std::make_unique<SceneRenderer>(scene, o.render, checked, backend);
#if SL_HAVE_MPI
  if (dist) {
    const CullParams cull{rs.mode, &scene.tf, rs.iso, enabled()};
    OutOfCoreRenderer& ooc = *r->out_of_core();
    ooc.set_sample_clip(dist->balance(*scene.source, ooc.layout(), rs.block, cull).clip);
  }
#endif
  return r;
}

std::unique_ptr<SceneRenderer> BenchRun::renderer_for(std::size_t mi, std::unique_ptr<SceneRenderer>& first) {
  rs.method = methods[mi];
  return mi == 0 ? std::move(first) : renderer();
}

Frame BenchRun::render(SceneRenderer& r, const Camera& camera, const Camera* next) const {
  Frame f = r.render(scene.tf, enabled(), camera, rs, next);
#if SL_HAVE_MPI
  if (dist) f = dist->composite(std::move(f), view_point(make_ray_generator(camera, rs.width, rs.height)));
#endif
  return f;
}

bool BenchRun::converged(const SceneRenderer& r) const {
  const bool c = r.out_of_core()->converged();
#if SL_HAVE_MPI
  if (dist) return dist->all(c);
#endif
  return c;
}

void write_reports(const BenchOptions& o, OutputFiles& outputs, const std::string& csv, const std::string& json) {
  if (!o.csv.empty()) outputs.write(o.csv, [&](const std::string& p) { write_file_atomic(p, csv); });
  if (!o.json.empty()) outputs.write(o.json, [&](const std::string& p) { write_file_atomic(p, json); });
}

void write_reports(BenchRun& b, const std::string& csv, const std::string& json) {
#if SL_HAVE_MPI
  if (b.dist && !b.dist->root()) return;
#endif
  write_reports(b.o, b.outputs, csv, json);
}

std::vector<int> parse_frame_list(const std::string& s) {
  std::vector<int> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    std::size_t end = 0;
    int v = 0;
    try {
      v = std::stoi(item, &end);
    } catch (const std::exception&) {
      end = 0;
    }
    if (end == 0 || end != item.size() || v < 1) throw InputError("--rss-at", "expected frame numbers >= 1, e.g. 100,1000,2000");
    out.push_back(v);
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double x = p * double(v.size() - 1);
  const std::size_t i = std::size_t(x);
  const double f = x - double(i);
  return i + 1 < v.size() ? v[i] * (1.0 - f) + v[i + 1] * f : v[i];
}

}  // namespace sl::app

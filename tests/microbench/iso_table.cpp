// sl_iso_table: the exact-vs-sampled isosurface table (the shape of seed 004's Table 6.2) on
// one volume: per filter (trilinear, tri-quadratic and tri-cubic B-spline) the exact method and sampling
// at steps 0.5 and 0.25 [SH05], each with the median ray-cast time and frames per second, the depth error
// against the filter's reference root (its exact method, LR81 to 1e-6 of a cell, which the tests check
// against a dense double-precision scan) and, for the sphere distance field, against the analytic sphere,
// and the pixels the sampled method misses. A program run by hand for numbers (never a
// timing assertion in a test, STYLE.md #11); ctest only smoke-runs it on tiny data.
//
//   sl_iso_table VOLUME ISO [SIZE] [REPEATS]
//   VOLUME: a file (NRRD, NIfTI, ...) or builtin:KIND[:XxYxZ] (neurites, blobs, organs, sphere)
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "cache/formats/volume_file.h"
#include "core/scene/generate.h"
#include "core/util/error.h"
#include "core/frame/in_core_renderer.h"

namespace sl {
namespace {

struct Result {
  std::string name;
  int ref = 0;  // index of the row holding this row's reference roots
  double raycast_ms = 0.0, total_ms = 0.0;
  std::vector<float> depth;
};

Result run(const Scene& scene, RenderSettings s, const std::string& name, int repeats) {
  Result r;
  r.name = name;
  std::vector<double> cast, total;
  for (int i = 0; i < repeats; ++i) {
    InCoreRenderer renderer;
    renderer.render(scene, s);  // warm: metadata, tree, lists
    const Frame f = renderer.render(scene, s);
    cast.push_back(f.stats.time_ms.raycast);
    total.push_back(f.stats.time_ms.total);
    if (i == 0) r.depth = f.image.channels.at("depth");
  }
  std::sort(cast.begin(), cast.end());
  std::sort(total.begin(), total.end());
  r.raycast_ms = cast[cast.size() / 2];
  r.total_ms = total[total.size() / 2];
  return r;
}

int main_impl(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: sl_iso_table VOLUME ISO [SIZE] [REPEATS]\n");
    return 2;
  }
  const std::string spec = argv[1];
  const float iso = std::strtof(argv[2], nullptr);
  const int size = argc > 3 ? std::atoi(argv[3]) : 512;
  const int repeats = argc > 4 ? std::atoi(argv[4]) : 3;
  Volume volume;
  bool sphere = false;
  if (spec.rfind("builtin:", 0) == 0) {
    std::string kind = spec.substr(8), dims_s = "256x256x256";
    if (const auto c = kind.find(':'); c != std::string::npos) {
      dims_s = kind.substr(c + 1);
      kind = kind.substr(0, c);
    }
    ivec3 d;
    if (std::sscanf(dims_s.c_str(), "%dx%dx%d", &d.x, &d.y, &d.z) != 3) throw InputError(spec, "dims");
    volume = std::move(generate_volume(kind, d, 1).intensity);
    sphere = kind == "sphere";
  } else {
    volume = read_volume_file(spec);
  }
  const vec2 range = value_range(volume);
  const TransferFunction tf = default_transfer_function(range.x, range.y);
  const Camera cam = default_camera(volume.desc().extent());
  const Scene scene{&volume, nullptr, &tf, nullptr, cam};
  RenderSettings s;
  s.width = s.height = size;
  s.mode = RenderMode::Iso;
  s.iso = iso;
  s.method = SkipMethod::SparseLeap;

  std::vector<Result> results;
  for (const Filter filter : {Filter::Linear, Filter::Quadratic, Filter::Cubic}) {
    s.filter = filter;
    const int ref = int(results.size());
    const std::string f = to_string(filter);
    s.step = 0.5f;  // exact roots do not depend on the step
    s.iso_method = IsoMethod::Exact;
    results.push_back(run(scene, s, f + " exact", repeats));
    results.back().ref = ref;
    s.iso_method = IsoMethod::Sampled;
    for (const float step : {0.5f, 0.25f}) {
      s.step = step;
      results.push_back(run(scene, s, f + " sampled " + std::to_string(step).substr(0, 4), repeats));
      results.back().ref = ref;
    }
  }
  const RayGenerator gen = make_ray_generator(cam, size, size);
  const vec3 centre = 0.5f * vec3(volume.dims());  // the sphere generator's centre (spacing 1)
  const double min_spacing = volume.desc().min_spacing();

  std::printf("volume %s (%dx%dx%d), iso %g, %dx%d, sparseleap, median of %d\n", spec.c_str(), volume.dims().x,
              volume.dims().y, volume.dims().z, iso, size, size, repeats);
  std::printf("%-24s %9s %7s %7s %10s %10s %6s %7s %6s%s\n", "method", "cast_ms", "fps", "hits", "err_max",
              "err_mean", "other", "missed", "extra", sphere ? "  sphere_max sphere_mean" : "");
  std::printf("(errors in voxels against the exact root where both hit within 0.5 voxel; other: both hit, farther\n"
              " apart (a crossing stepped over); missed: exact hits, this one does not; extra: the reverse)\n");
  for (const Result& r : results) {
    const std::vector<float>& ref = results[std::size_t(r.ref)].depth;
    double max_e = 0.0, sum_e = 0.0, smax = 0.0, ssum = 0.0;
    long both = 0, other = 0, missed = 0, extra = 0, hits = 0, shits = 0;
    for (int i = 0; i < size * size; ++i) {
      const bool a = ref[i] >= 0.0f, b = r.depth[i] >= 0.0f;
      hits += b;
      if (a && !b) ++missed;
      if (b && !a) ++extra;
      if (a && b) {
        const double e = std::fabs(double(r.depth[i]) - double(ref[i])) / min_spacing;
        if (e > 0.5) {
          ++other;  // a different (later) surface: the first crossing was stepped over
        } else {
          max_e = std::max(max_e, e);
          sum_e += e;
          ++both;
        }
      }
      if (sphere && b) {
        const Ray ray = gen.ray(i % size, i / size);
        const glm::dvec3 oc = glm::dvec3(ray.origin) - glm::dvec3(centre), d(ray.dir);
        const double bb = glm::dot(oc, d), disc = bb * bb - (glm::dot(oc, oc) - double(iso) * iso);
        if (disc >= 0.0) {
          const double e = std::fabs(double(r.depth[i]) - (-bb - std::sqrt(disc)));
          smax = std::max(smax, e);
          ssum += e;
          ++shits;
        }
      }
    }
    std::printf("%-24s %9.1f %7.2f %7ld %10.2e %10.2e %6ld %7ld %6ld", r.name.c_str(), r.raycast_ms,
                1000.0 / r.total_ms, hits, max_e, both ? sum_e / both : 0.0, other, missed, extra);
    if (sphere) std::printf("  %10.4f %11.4f", smax, shits ? ssum / shits : 0.0);
    std::printf("\n");
  }
  return 0;
}

}  // namespace
}  // namespace sl

int main(int argc, char** argv) {
  try {
    return sl::main_impl(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sl_iso_table: error: %s\n", e.what());
    return 1;
  }
}

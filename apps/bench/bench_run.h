// What a `sparseleap bench` run shares between its in-core and out-of-core halves: the options, the
// loaded scene and path, a renderer per method, and writing the reports.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "apps/backend.h"
#include "apps/outputs.h"
#include "apps/render_options.h"
#include "apps/scene_renderer.h"
#include "core/scene/camera_path.h"

namespace sl::app {

class Distributed;  // apps/distributed.h (SL_MPI builds)

constexpr const char* kAllMethods = "none,bbox,octree,sparseleap";

struct BenchOptions {
  RenderOptions render;
  std::string path;
  int orbit = 24;
  std::string methods = kAllMethods;
  bool methods_given = false;  // out of core the default is sparseleap
  int warmup = 1;
  bool warmup_given = false;  // out of core the default is 0: a view's cold start is what it measures
  std::string csv, json;
  int max_frames_per_view = 40;
  std::string path_kind = "orbit";  // generated path: orbit, orbit-zoom, zoom-in
  bool path_kind_given = false;
  std::string rss_at;               // out of core: frame numbers (1-based, per method) to report RSS at
  int max_frames = 0;               // out of core: frames per method at most (0: the whole path)
  // --loader: time the brick loader alone instead of rendering (apps/bench/loader.h).
  bool loader = false;
  int loader_bricks = 4096;  // level-0 bricks per pass, centre first
  int loader_passes = 5;     // passes, each with a fresh loader
};

// Everything a bench run shares, whichever path renders it.
struct BenchRun {
  const BenchOptions& o;
  const CheckedOptions& checked;
  const SourceScene& scene;
  const CameraPath& path;
  const std::vector<SkipMethod>& methods;
  int warmup;
  Backend backend;
  RenderSettings rs;
  OutputFiles& outputs;  // --csv, --json: checked before the run
  Distributed* dist = nullptr;  // --distributed: this rank's share of the job

  const LabelSet* enabled() const { return scene.enabled ? &*scene.enabled : nullptr; }
  std::unique_ptr<SceneRenderer> renderer() const;
  // The renderer of method `mi` (and rs.method set to it): `first` for the first method (made before
  // the run, so bad settings fail before any output), a fresh one for the others.
  std::unique_ptr<SceneRenderer> renderer_for(std::size_t mi, std::unique_ptr<SceneRenderer>& first);
  // One frame of `camera`: distributed, every rank's region composited (rank 0 holds the image).
  // `next`: the view expected next (prefetch along the motion).
  Frame render(SceneRenderer& r, const Camera& camera, const Camera* next = nullptr) const;
  // Nothing left to load or resolve (distributed: on every rank).
  bool converged(const SceneRenderer& r) const;
};

// The CSV and JSON reports (those asked for, o.csv and o.json), as one set: a failing second one
// removes the first. Distributed, rank 0 writes them.
void write_reports(const BenchOptions& o, OutputFiles& outputs, const std::string& csv, const std::string& json);
void write_reports(BenchRun& b, const std::string& csv, const std::string& json);

// `--rss-at 100,1000,2000`: ascending frame numbers >= 1.
std::vector<int> parse_frame_list(const std::string& s);

// The p-quantile of `v`, interpolated between neighbours (0 for none).
double percentile(std::vector<double> v, double p);

// The two halves of a run; each prints its table and writes the reports. `first` renders the first
// method.
int bench_in_core(BenchRun& b, std::unique_ptr<SceneRenderer> first);
int bench_out_of_core(BenchRun& b, std::unique_ptr<SceneRenderer> first);

}  // namespace sl::app

// `sparseleap gen KIND`: deterministic synthetic volumes written as NRRD.
#include <cstdio>
#include <memory>
#include <regex>

#include "apps/commands.h"
#include "apps/outputs.h"
#include "apps/scene_loader.h"
#include "core/scene/generate.h"
#include "cache/formats/nrrd/nrrd.h"
#include "core/util/error.h"
#include "core/frame/stats.h"

namespace sl::app {

namespace {

struct GenOptions {
  std::string kind;
  std::string dims = "256x256x256";
  std::string out;
  std::string labels_out;
  unsigned seed = 1;
  bool gzip = false;
};

ivec3 parse_dims(const std::string& s) {
  static const std::regex re("^([0-9]{1,7})[xX]([0-9]{1,7})[xX]([0-9]{1,7})$");
  std::smatch m;
  if (!std::regex_match(s, m, re)) throw InputError("--dims", "expected XxYxZ, e.g. 512x512x256, got '" + s + "'");
  return ivec3(std::stoi(m[1]), std::stoi(m[2]), std::stoi(m[3]));
}

int run_gen(const GenOptions& o) {
  const ivec3 dims = parse_dims(o.dims);
  const std::string out = o.out.empty() ? o.kind + ".nrrd" : o.out;
  const bool labelled = generated_kind_has_labels(o.kind);  // throws for an unknown kind
  std::string lout = o.labels_out;
  if (lout.empty()) {
    const auto dot = out.rfind('.');
    lout = (dot == std::string::npos ? out : out.substr(0, dot)) + "_labels" +
           (dot == std::string::npos ? ".nrrd" : out.substr(dot));
  }
  // Every output's folder and name checked before the volume is generated, so that a bad label
  // path cannot leave a complete intensity volume behind (or fail after minutes of work).
  OutputFiles outputs;
  const auto files = [&](const std::string& p) {
    std::vector<std::string> f = nrrd_output_files(p, o.gzip);
    return std::vector<std::string>(f.begin() + 1, f.end());
  };
  outputs.add(out, files(out));
  if (labelled) outputs.add(lout, files(lout));
  std::uint64_t bytes = 0;
  try {
    bytes = generated_bytes(o.kind, dims);
  } catch (const InputError& e) {
    throw InputError("--dims", e.reason());  // the kind is known: the dims are what is wrong
  }
  check_fits_in_memory(bytes, "--dims", o.kind + " " + o.dims);
  Timer t;
  GeneratedVolume g = generate_volume(o.kind, dims, o.seed);
  outputs.write(out, [&](const std::string& p) { write_nrrd(p, g.intensity, o.gzip); });
  if (labelled) outputs.write(lout, [&](const std::string& p) { write_nrrd(p, g.labels, o.gzip); });
  std::printf("wrote %s (%dx%dx%d %s) in %.1f s\n", out.c_str(), dims.x, dims.y, dims.z,
              to_string(g.intensity.type()), t.ms() / 1000.0);
  if (labelled) std::printf("wrote %s (%u labels)\n", lout.c_str(), g.label_count);
  return 0;
}

}  // namespace

Runner add_gen_command(CLI::App& app) {
  auto o = std::make_shared<GenOptions>();
  CLI::App* c = app.add_subcommand("gen", "Generate a synthetic volume (neurites, blobs, organs, sphere) as NRRD");
  c->add_option("kind", o->kind, "neurites, blobs, organs or sphere")->required();
  c->add_option("--dims", o->dims, "Dimensions XxYxZ (any sizes)")->capture_default_str();
  c->add_option("--out", o->out, "Output NRRD (.nrrd attached, .nhdr detached); default KIND.nrrd");
  c->add_option("--labels-out", o->labels_out, "Label volume output; default OUT_labels.nrrd");
  c->add_option("--seed", o->seed, "Random seed")->capture_default_str();
  c->add_flag("--gzip", o->gzip, "gzip-encode the data");
  return [o] { return run_gen(*o); };
}

}  // namespace sl::app

// `sparseleap info PATH`: what a volume file holds.
#include <cstdio>
#include <filesystem>
#include <memory>

#include "apps/commands.h"
#include "cache/nrrd.h"
#include "core/error.h"

namespace sl::app {

Runner add_info_command(CLI::App& app) {
  auto path = std::make_shared<std::string>();
  auto full = std::make_shared<bool>(false);
  CLI::App* c = app.add_subcommand("info", "Print dims, type, spacing and value range of a volume");
  c->add_option("path", *path, "Volume file (NRRD)")->required();
  c->add_flag("--stats", *full, "Also read the data and print the value range");
  return [path, full] {
    const VolumeDesc d = read_nrrd_header(*path);
    std::printf("%s\n  dims    %d x %d x %d\n  type    %s\n  spacing %g %g %g\n  size    %.1f MiB\n",
                path->c_str(), d.dims.x, d.dims.y, d.dims.z, to_string(d.type), d.spacing.x, d.spacing.y,
                d.spacing.z, double(d.byte_size()) / (1024.0 * 1024.0));
    if (*full) {
      const Volume v = read_nrrd(*path);
      const vec2 r = value_range(v);
      std::printf("  range   %g .. %g\n", r.x, r.y);
    }
    return 0;
  };
}

}  // namespace sl::app

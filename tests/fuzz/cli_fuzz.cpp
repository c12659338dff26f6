// The command line's value parsers (apps/render_options.cpp through CLI11, core/scene/labels.cpp's
// --enable, the procedural volume spec): the input is argv, one argument a line; the first picks
// render, bench or view. Parsed as main() does, checked as every command does before loading data.
#include <cstdint>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "apps/render_options.h"
#include "cache/synthetic/procedural_neurites.h"
#include "core/util/error.h"
#include "core/scene/labels.h"
#include "tests/fuzz/fuzz_util.h"

SL_FUZZ_TARGET(input) {
  std::vector<std::string> args;
  for (const auto a : sl::fuzz::split(input, "\n", 64)) args.emplace_back(a);
  if (args.size() < 2) return;
  CLI::App app{"fuzz"};
  app.require_subcommand(1);
  sl::app::RenderOptions o[3];
  const char* const names[] = {"render", "bench", "view"};
  const sl::app::Command cmds[] = {sl::app::Command::Render, sl::app::Command::Bench, sl::app::Command::View};
  for (int i = 0; i < 3; ++i) {
    o[i].size = i == 2 ? "800x600" : "1024x1024";
    sl::app::add_render_options(*app.add_subcommand(names[i]), o[i], cmds[i]);
  }
  std::vector<std::string> argv(args.rbegin(), args.rend() - 1);  // CLI11 takes them last first
  try {
    app.parse(argv);
  } catch (const CLI::ParseError&) {
    return;  // a syntax error: main() prints it and exits 2
  }
  for (const sl::app::RenderOptions& r : o) {
    sl::fuzz::accepted([&] {
      sl::app::check_render_options(r);
      if (!r.scene.enable.empty()) sl::parse_enable_spec(r.scene.enable, 1000);
      if (sl::is_procedural_spec(r.scene.volume)) sl::parse_volume_spec(r.scene.volume);
      return true;
    });
  }
}

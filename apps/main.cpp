// sparseleap: out-of-core, ray-guided volume rendering with SparseLeap empty-space skipping.
// Errors in input are caught here once and printed as one line with a non-zero exit (DESIGN.md §10).
#include <cstdio>
#include <exception>
#include <map>
#include <string>

#include "apps/commands.h"
#include "core/error.h"

int main(int argc, char** argv) {
  CLI::App app{"sparseleap: out-of-core volume renderer with SparseLeap empty-space skipping"};
  app.require_subcommand(1);
  std::map<CLI::App*, sl::app::Runner> runners;
  auto add = [&](sl::app::Runner (*fn)(CLI::App&)) {
    const std::size_t before = app.get_subcommands({}).size();
    sl::app::Runner r = fn(app);
    runners[app.get_subcommands({})[before]] = std::move(r);
  };
  add(sl::app::add_render_command);
  add(sl::app::add_gen_command);
  add(sl::app::add_info_command);
  add(sl::app::add_bench_command);
  add(sl::app::add_view_command);
  add(sl::app::add_ingest_command);

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "sparseleap: %s\n", e.what());
    return 2;
  }
  try {
    for (auto& [sub, run] : runners) {
      if (sub->parsed()) return run();
    }
  } catch (const sl::InputError& e) {
    std::fprintf(stderr, "sparseleap: error: %s\n", e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "sparseleap: error: out of memory\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sparseleap: internal error: %s\n", e.what());
    return 3;
  }
  return 0;
}

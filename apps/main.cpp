// sparseleap: out-of-core, ray-guided volume rendering with SparseLeap empty-space skipping.
// Errors in input are caught here once and printed as one line with a non-zero exit (DESIGN.md "Conventions").
#include <cstdio>
#include <exception>
#include <map>
#include <string>

#include "apps/commands.h"
#include "core/util/error.h"
#include "core/util/printable.h"

namespace {

void print_error(const char* kind, const std::string& what) {
  std::fprintf(stderr, "sparseleap: %s%s\n", kind, sl::printable(what).c_str());
}

}  // namespace

int sl::app::report_error(std::exception_ptr error) {
  try {
    std::rethrow_exception(error);
  } catch (const sl::InputError& e) {
    print_error("error: ", e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    print_error("error: ", "out of memory");
    return 1;
  } catch (const std::exception& e) {
    print_error("internal error: ", e.what());
    return 3;
  }
  return 3;
}

int main(int argc, char** argv) {
  CLI::App app{"sparseleap: out-of-core volume renderer with SparseLeap empty-space skipping"};
  app.require_subcommand(1);
  app.footer("The reference of every command and option: docs/cli.md");
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

  // CLI11 takes an unknown command for a stray argument ("A subcommand is required"): name it.
  bool known = argc < 2 || argv[1][0] == '-';
  for (const auto& entry : runners) known = known || entry.first->check_name(argv[1]);
  if (!known) {
    print_error("", std::string("unknown command '") + argv[1] + "' (expected render, gen, info, bench, view or ingest)");
    return 2;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    print_error("", e.what());
    return 2;
  } catch (const sl::InputError&) {  // an option's value refused while parsing (render_options.cpp)
    return sl::app::report_error(std::current_exception());
  }
  try {
    for (auto& [sub, run] : runners) {
      if (sub->parsed()) return run();
    }
  } catch (...) {
    return sl::app::report_error(std::current_exception());
  }
  return 0;
}

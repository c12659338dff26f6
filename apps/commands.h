// The `sparseleap` subcommands. Each registers its options on the CLI11 app and runs when chosen.
#pragma once

#include <CLI/CLI.hpp>
#include <exception>
#include <functional>

namespace sl::app {

// Registers a subcommand; the returned function runs it (after parsing) and returns the exit code.
using Runner = std::function<int()>;
Runner add_render_command(CLI::App& app);
Runner add_gen_command(CLI::App& app);
Runner add_info_command(CLI::App& app);
Runner add_bench_command(CLI::App& app);
Runner add_view_command(CLI::App& app);
Runner add_ingest_command(CLI::App& app);

// Prints the one error line for `error` on stderr ("sparseleap: error: …" for bad input and
// out of memory, "sparseleap: internal error: …" otherwise) and returns the exit code (1 or 3).
int report_error(std::exception_ptr error);

}  // namespace sl::app

// `sparseleap bench --loader`: the brick loader's throughput on its own, without rendering. The volume
// is opened as render and bench open it out of core (any store, URL, --disk-cache, procedural), and a
// fixed set of level-0 bricks, nearest the centre first, is read through a BrickLoader with the
// renderer's thread count, as the renderer would when a view first asks for them.
#pragma once

#include <cstdint>
#include <vector>

#include "apps/bench/bench_run.h"
#include "apps/outputs.h"
#include "cache/brick.h"

namespace sl::app {

// `--loader-bricks` and `--loader-passes` bounds.
inline constexpr int kMaxLoaderBricks = 10'000'000;
inline constexpr int kMaxLoaderPasses = 100;

// The `count` level-0 bricks of `layout` whose payload centres lie nearest the volume's centre (world
// distance, so anisotropic spacing counts), nearest first, ties in id order; all of them, in that
// order, when the level has fewer. Only the bricks around the centre are looked at, so a level of
// millions of bricks costs what `count` costs.
std::vector<BrickId> centre_first_bricks(const BrickLayout& layout, std::uint64_t count);

// Opens the volume out of core and times o.loader_passes passes of loading o.loader_bricks bricks;
// prints a table (a line per pass and the median) and writes --json and --csv (registered in
// `outputs`). Every pass opens a streamed source afresh, so its chunk caches start empty and each pass
// reads what the first does (a --disk-cache and the system's file cache still serve later passes).
int bench_loader(const BenchOptions& o, OutputFiles& outputs);

}  // namespace sl::app

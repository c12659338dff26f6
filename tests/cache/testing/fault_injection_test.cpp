#include "cache/testing/fault_injection.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <thread>
#include <vector>

#include "core/scene/generate.h"
#include "core/util/error.h"

namespace sl {
namespace {

std::shared_ptr<MemoryVolumeSource> small_source() {
  const GeneratedVolume g = generate_volume("neurites", {40, 30, 20}, 3);
  return std::make_shared<MemoryVolumeSource>(std::make_shared<Volume>(g.intensity),
                                              std::make_shared<Volume>(g.labels), "neurites");
}

std::string parse_error(const std::string& spec) {
  try {
    parse_fault_spec(spec);
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "--inject-faults");
    return e.reason();
  }
  return "<accepted>";
}

TEST(FaultSpec, ParsesEveryKeyInAnyOrder) {
  const FaultSpec s = parse_fault_spec("seed=7,short=0.02,permanent=0.02,transient=0.06,recover=3,delay=0.1,delay-ms=5");
  EXPECT_EQ(s.permanent, 0.02);
  EXPECT_EQ(s.transient, 0.06);
  EXPECT_EQ(s.short_read, 0.02);
  EXPECT_EQ(s.recover, 3);
  EXPECT_EQ(s.delay, 0.1);
  EXPECT_EQ(s.delay_ms, 5);
  EXPECT_EQ(s.seed, 7u);
  const FaultSpec d = parse_fault_spec("transient=1");
  EXPECT_EQ(d.permanent, 0.0);
  EXPECT_EQ(d.recover, 2);
}

TEST(FaultSpec, BadSpecsNameTheProblem) {
  EXPECT_NE(parse_error("").find("empty"), std::string::npos);
  EXPECT_NE(parse_error("permanent=1.5").find("permanent must be a share in [0, 1]"), std::string::npos);
  EXPECT_NE(parse_error("transient=-0.1").find("transient"), std::string::npos);
  EXPECT_NE(parse_error("short=nan").find("short"), std::string::npos);
  EXPECT_NE(parse_error("permanent=0.6,transient=0.6").find("must not exceed 1"), std::string::npos);
  EXPECT_NE(parse_error("bogus=1").find("unknown key 'bogus'"), std::string::npos);
  EXPECT_NE(parse_error("permanent").find("key=value"), std::string::npos);
  EXPECT_NE(parse_error("seed=1,seed=2").find("given twice"), std::string::npos);
  EXPECT_NE(parse_error("recover=0").find("recover must be an integer"), std::string::npos);
  EXPECT_NE(parse_error("delay-ms=5ms").find("delay-ms"), std::string::npos);
  EXPECT_NE(parse_error("seed=-3").find("seed"), std::string::npos);
  EXPECT_NE(parse_error("permanent=0.1,").find("key=value"), std::string::npos);
}

TEST(FaultSpec, SharesAndRecoveryFollowTheSpecDeterministically) {
  FaultSpec s;
  s.permanent = 0.05;
  s.transient = 0.10;
  s.short_read = 0.05;
  s.recover = 3;
  s.delay = 0.2;
  s.seed = 11;
  int counts[4] = {}, delayed = 0;
  std::vector<int> attempts(4, 0);
  const int n = 100000;
  for (int i = 0; i < n; ++i) {
    const BrickId id = BrickId::pack(i % 3, {i % 97, (i / 97) % 89, i / (97 * 89)});
    const BrickFault f = s.fault(id);
    EXPECT_EQ(f.kind, s.fault(id).kind);  // a pure function of (seed, id)
    ++counts[int(f.kind)];
    if (f.kind == FaultKind::Transient || f.kind == FaultKind::ShortRead) {
      ASSERT_GE(f.failing_attempts, 1);
      ASSERT_LE(f.failing_attempts, 3);
      ++attempts[std::size_t(f.failing_attempts)];
    } else {
      EXPECT_EQ(f.failing_attempts, 0);
    }
    delayed += s.delayed(id, 0) ? 1 : 0;
  }
  // Hash-uniform: within 1 % (absolute) of each share over 100k bricks.
  EXPECT_NEAR(counts[int(FaultKind::Permanent)] / double(n), 0.05, 0.01);
  EXPECT_NEAR(counts[int(FaultKind::Transient)] / double(n), 0.10, 0.01);
  EXPECT_NEAR(counts[int(FaultKind::ShortRead)] / double(n), 0.05, 0.01);
  EXPECT_NEAR(delayed / double(n), 0.2, 0.01);
  for (int k = 1; k <= 3; ++k) EXPECT_GT(attempts[std::size_t(k)], 0) << "k = " << k;
  // Another seed picks other bricks.
  FaultSpec t = s;
  t.seed = 12;
  int same = 0;
  for (int i = 0; i < 1000; ++i) {
    const BrickId id = BrickId::pack(0, {i, 0, 0});
    same += s.fault(id).kind == t.fault(id).kind ? 1 : 0;
  }
  EXPECT_LT(same, 900);
}

// Brick ids of `layout` whose spec fault is `kind`.
std::vector<BrickId> bricks_of_kind(const BrickLayout& layout, const FaultSpec& s, FaultKind kind) {
  std::vector<BrickId> ids;
  for (int level = 0; level < layout.levels; ++level) {
    const ivec3 n = layout.bricks(level);
    for (int z = 0; z < n.z; ++z)
      for (int y = 0; y < n.y; ++y)
        for (int x = 0; x < n.x; ++x) {
          const BrickId id = BrickId::pack(level, {x, y, z});
          if (s.fault(id).kind == kind) ids.push_back(id);
        }
  }
  return ids;
}

struct Buffers {
  std::vector<std::byte> intensity, labels;
  Buffers(const BrickLayout& l, const VolumeSource& s)
      : intensity(l.stored_voxels() * voxel_size(s.desc().type)), labels(l.stored_voxels() * voxel_size(s.label_type())) {}
};

TEST(FaultInjectingSource, EachKindFailsAsTheSpecSays) {
  const auto inner = small_source();
  const BrickLayout layout = BrickLayout::make(inner->desc(), 8);
  FaultSpec spec;
  spec.permanent = 0.2;
  spec.transient = 0.3;
  spec.short_read = 0.3;
  spec.recover = 3;
  spec.seed = 5;
  const FaultInjectingSource src(inner, spec);
  EXPECT_EQ(src.name(), "neurites");
  EXPECT_EQ(src.desc().dims, inner->desc().dims);

  Buffers want(layout, *inner), got(layout, *inner);
  const auto permanent = bricks_of_kind(layout, spec, FaultKind::Permanent);
  ASSERT_FALSE(permanent.empty());
  for (const BrickId id : permanent) {
    for (int attempt = 0; attempt < 6; ++attempt) {
      try {
        src.read_brick(layout, id, got.intensity, got.labels);
        ADD_FAILURE() << "a permanent fault read";
      } catch (const TransientError&) {
        ADD_FAILURE() << "a permanent fault is not transient";
      } catch (const InputError& e) {
        EXPECT_EQ(e.file(), "neurites");
        EXPECT_EQ(e.reason(), "injected read error in " + to_string(id));
      }
    }
    EXPECT_EQ(src.attempts(id), 6);
  }

  for (const FaultKind kind : {FaultKind::Transient, FaultKind::ShortRead}) {
    const auto ids = bricks_of_kind(layout, spec, kind);
    ASSERT_FALSE(ids.empty());
    for (const BrickId id : ids) {
      inner->read_brick(layout, id, want.intensity, want.labels);
      const int k = spec.fault(id).failing_attempts;
      for (int attempt = 0; attempt < k; ++attempt) {
        try {
          src.read_brick(layout, id, got.intensity, got.labels);
          ADD_FAILURE() << "attempt " << attempt << " of " << k << " should fail";
        } catch (const TransientError& e) {
          const std::string r = e.reason();
          if (kind == FaultKind::ShortRead) {
            // "short read: N of M bytes": the first N bytes arrived, the rest is garbage.
            const std::size_t total = want.intensity.size() + want.labels.size();
            std::size_t n = 0;
            ASSERT_EQ(std::sscanf(r.c_str(), "short read: %zu of", &n), 1) << r;
            EXPECT_NE(r.find(" of " + std::to_string(total) + " bytes"), std::string::npos) << r;
            ASSERT_LT(n, total);
            for (std::size_t i = 0; i < total; ++i) {
              const std::byte w = i < want.intensity.size() ? want.intensity[i] : want.labels[i - want.intensity.size()];
              const std::byte g = i < got.intensity.size() ? got.intensity[i] : got.labels[i - got.intensity.size()];
              ASSERT_EQ(g, i < n ? w : std::byte{0xA5}) << "byte " << i << " of " << r;
            }
          } else {
            EXPECT_NE(r.find("injected transient error in " + to_string(id)), std::string::npos) << r;
          }
        }
      }
      // Then it reads, on every later attempt.
      for (int again = 0; again < 2; ++again) {
        src.read_brick(layout, id, got.intensity, got.labels);
        EXPECT_EQ(got.intensity, want.intensity);
        EXPECT_EQ(got.labels, want.labels);
      }
    }
  }
  for (const BrickId id : bricks_of_kind(layout, spec, FaultKind::None)) {
    inner->read_brick(layout, id, want.intensity, want.labels);
    src.read_brick(layout, id, got.intensity, got.labels);
    EXPECT_EQ(got.intensity, want.intensity);
    EXPECT_EQ(src.attempts(id), 1);
  }
}

// Faults hit brick reads only: the wrapped source's bounds and pyramid are the inner source's, and a
// read with bounds fails as a plain read does and otherwise returns the inner source's voxels and bounds.
TEST(FaultInjectingSource, ForwardsBoundsAndPyramidAndFaultsBoundedReads) {
  const GeneratedVolume g = generate_volume("neurites", {40, 30, 20}, 3);
  const auto inner = std::make_shared<MemoryVolumeSource>(std::make_shared<Volume>(g.intensity), nullptr, "neurites",
                                                          PyramidKind::Max);
  const BrickLayout layout = BrickLayout::make(inner->desc(), 8);
  ASSERT_GE(layout.levels, 3);
  FaultSpec spec;
  spec.permanent = 0.3;
  spec.seed = 11;
  const FaultInjectingSource src(inner, spec);
  EXPECT_EQ(src.pyramid(), PyramidKind::Max);

  const int block = 4;
  const std::vector<ivec3> blocks = {{0, 0, 0}, {1, 0, 0}, {0, 1, 1}};
  std::vector<BlockMetadata> want_bounds(blocks.size()), got_bounds(blocks.size());
  ASSERT_TRUE(inner->bound_blocks(layout, 1, block, blocks, want_bounds));
  ASSERT_TRUE(src.bound_blocks(layout, 1, block, blocks, got_bounds));
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    EXPECT_EQ(got_bounds[i].min, want_bounds[i].min);
    EXPECT_EQ(got_bounds[i].max, want_bounds[i].max);
  }

  Buffers want(layout, *inner), got(layout, *inner);
  int healthy = 0, failing = 0;
  for (const BrickId id : bricks_of_kind(layout, spec, FaultKind::None)) {
    if (id.level() == 0) continue;
    std::vector<BlockMetadata> a, b;
    inner->read_brick_bounded(layout, id, want.intensity, {}, block, a);
    src.read_brick_bounded(layout, id, got.intensity, {}, block, b);
    EXPECT_EQ(got.intensity, want.intensity);
    ASSERT_EQ(b.size(), a.size());
    ASSERT_FALSE(a.empty()) << "a coarse brick of a bounded source comes with its bounds";
    for (std::size_t i = 0; i < a.size(); ++i) EXPECT_EQ(b[i].max, a[i].max);
    ++healthy;
  }
  for (const BrickId id : bricks_of_kind(layout, spec, FaultKind::Permanent)) {
    std::vector<BlockMetadata> b;
    EXPECT_THROW(src.read_brick_bounded(layout, id, got.intensity, {}, block, b), InputError);
    EXPECT_EQ(src.attempts(id), 1);
    ++failing;
  }
  EXPECT_GT(healthy, 0);
  EXPECT_GT(failing, 0);
}

TEST(FaultInjectingSource, CountsAttemptsAcrossThreads) {
  const auto inner = small_source();
  const BrickLayout layout = BrickLayout::make(inner->desc(), 8);
  FaultSpec spec;
  spec.transient = 1.0;
  spec.recover = 1000;  // fails (almost) every attempt of the test
  const FaultInjectingSource src(inner, spec);
  const BrickId id = BrickId::pack(0, {1, 1, 1});
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&] {
      Buffers b(layout, *inner);
      for (int i = 0; i < 50; ++i) {
        try {
          src.read_brick(layout, id, b.intensity, b.labels);
        } catch (const TransientError&) {
        }
      }
    });
  }
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(src.attempts(id), 200);  // every attempt counted once: no lost updates
}

}  // namespace
}  // namespace sl

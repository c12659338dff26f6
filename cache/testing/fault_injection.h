// Fault injection for out-of-core streaming, a testing aid: FaultInjectingSource wraps any
// VolumeSource and makes a chosen share of its bricks fail to read — for good, transiently (for the
// first k attempts), as a short read (part of the buffer filled, then a TransientError) — or read
// slowly. What happens to a read is a pure function of (seed, brick id, attempt number), never of
// timing or thread scheduling, so a run and its tests are repeatable and the set of bricks that must
// end up failed is known in advance (FaultSpec::fault).
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

#include "cache/brick.h"
#include "cache/volume_source.h"

namespace sl {

enum class FaultKind : std::uint8_t { None, Permanent, Transient, ShortRead };

// What the spec does to one brick: its kind and for how many attempts it fails (Permanent: every
// attempt; Transient/ShortRead: the first `failing_attempts`, then it reads).
struct BrickFault {
  FaultKind kind = FaultKind::None;
  int failing_attempts = 0;
};

struct FaultSpec {
  // Shares of bricks, each in [0, 1], summing to at most 1: every brick gets at most one fault kind.
  double permanent = 0, transient = 0, short_read = 0;
  int recover = 2;     // a transient or short-read brick fails its first k attempts, k uniform in [1, recover]
  double delay = 0;    // share of reads (per brick and attempt) delayed by delay_ms
  int delay_ms = 20;
  std::uint64_t seed = 1;

  BrickFault fault(BrickId id) const;
  // Whether attempt `attempt` (0 = first) of brick `id` is delayed.
  bool delayed(BrickId id, int attempt) const;
  // permanent + transient + short_read.
  double fault_share() const { return permanent + transient + short_read; }
};

// "permanent=F,transient=F,short=F,recover=K,delay=F,delay-ms=D,seed=S" (any subset, any order).
// Throws InputError(option, reason) naming the bad key or value.
FaultSpec parse_fault_spec(const std::string& text, const std::string& option = "--inject-faults");

class FaultInjectingSource final : public VolumeSource {
 public:
  FaultInjectingSource(std::shared_ptr<const VolumeSource> inner, const FaultSpec& spec);

  const VolumeDesc& desc() const override { return inner_->desc(); }
  bool has_labels() const override { return inner_->has_labels(); }
  VoxelType label_type() const override { return inner_->label_type(); }
  const std::string& name() const override { return inner_->name(); }
  // Counts the attempt, sleeps if the spec delays it, then fails or reads as the spec says. A short
  // read leaves the rest of the buffer overwritten (0xA5), so a loader that kept it would be caught.
  void read_brick(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                  std::span<std::byte> out_labels) const override;
  // The same faults, on a read of the brick with its culling bounds.
  void read_brick_bounded(const BrickLayout& layout, BrickId id, std::span<std::byte> out_intensity,
                          std::span<std::byte> out_labels, int block,
                          std::vector<BlockMetadata>& bounds) const override;
  // The inner source's bounds and pyramid: faults hit brick reads only, so a wrapped source culls
  // and shows what it does unwrapped.
  bool bound_blocks(const BrickLayout& layout, int level, int block, std::span<const ivec3> blocks,
                    std::span<BlockMetadata> out) const override {
    return inner_->bound_blocks(layout, level, block, blocks, out);
  }
  PyramidKind pyramid() const override { return inner_->pyramid(); }

  const FaultSpec& spec() const { return spec_; }
  // Reads of `id` so far (its next attempt number).
  int attempts(BrickId id) const;

 private:
  // Counts the attempt, delays it, fails it or calls read(), as the spec says for brick `id`.
  template <class Read>
  void faulty_read(BrickId id, std::span<std::byte> out_intensity, std::span<std::byte> out_labels,
                   Read&& read) const;

  std::shared_ptr<const VolumeSource> inner_;
  FaultSpec spec_;
  mutable std::mutex mutex_;
  mutable std::unordered_map<BrickId, int, BrickIdHash> attempts_;
};

}  // namespace sl

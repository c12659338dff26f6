// A CPU stand-in for a GPU cast device (pbrt-v4's "CPU mode runs the GPU-shaped pipeline"): it keeps
// its OWN page table (directory + pool), slot pool, miss buffer and usage stamps — "device memory" —
// and learns about the host's state only through the CastDevice calls, with the CUDA device's timing:
// brick uploads complete at the next frame boundary (like copies on a stream that overlaps the
// frame's kernel), and page-table words naming an in-flight slot become visible only then. It casts
// with the same CPU caster (VirtualSampler over its copies) and hands misses and usage back by copy.
// The counters say exactly what crossed the "bus", so tests can prove the host uploads only new
// bricks and dirty page-table words.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "cache/out_of_core/cast_device.h"

namespace sl {

struct SimulatedTransfers {
  std::uint64_t bricks_uploaded = 0;      // bricks copied to slots (total)
  std::uint64_t brick_bytes = 0;          // their bytes (voxels + labels)
  std::uint64_t page_words = 0;           // page-table words received (directory + pool)
  std::uint64_t page_words_deferred = 0;  // of those, held back until their slot's upload landed
  std::uint64_t frames = 0;
  std::uint64_t misses_returned = 0;
  std::uint64_t usage_returned = 0;       // used-slot entries copied back
};

class SimulatedCastDevice final : public CastDevice {
 public:
  const char* name() const override { return "simulated"; }
  bool shares_host_memory() const override { return false; }
  bool casts_on_host() const override { return true; }
  void configure(const DeviceConfig& config) override;
  void begin_frame() override;
  void upload_bricks(std::span<const BrickUpload> bricks) override;
  void sync_page_table(const PageTableUpdate& update) override;
  void cast(const CastRequest& request, Frame& frame, CastFeedback& feedback) override;

  // Totals and the last frame's transfers (reset by begin_frame).
  const SimulatedTransfers& total() const { return total_; }
  const SimulatedTransfers& last_frame() const { return this_frame_; }
  // The device's own page-table entry of a brick (tests compare it with the host's).
  PageEntry entry(BrickId id) const;
  // Bricks whose upload has been issued but not yet landed.
  std::size_t in_flight() const { return uploads_in_flight_.size(); }
  // The bytes of a slot in the device pool (tests).
  std::span<const std::byte> slot_voxels(std::uint32_t slot) const;

 private:
  struct UploadInFlight {
    std::uint32_t slot;
    std::vector<std::byte> voxels, labels;
  };
  void write_page_words(const PageTableUpdate& u);  // into the device's directory and pool
  VirtualMemoryView device_view();  // the caster's view of the device's own copies

  DeviceConfig config_{};
  std::uint64_t voxel_stride_ = 0, label_stride_ = 0;
  std::vector<std::byte> voxels_, labels_;  // the slot pool
  std::vector<std::uint32_t> usage_;
  std::vector<std::uint64_t> shortfall_;   // SampleShortfall counters of the cast
  std::vector<std::uint32_t> directory_, pool_;
  std::unique_ptr<MissBuffer> misses_;
  std::vector<UploadInFlight> uploads_in_flight_;  // landing at the next begin_frame
  std::vector<bool> slot_in_flight_;               // per slot: its upload has not landed
  PageTableUpdate held_words_;                     // page-table words waiting for their slot's upload
  SimulatedTransfers total_, this_frame_;
};

}  // namespace sl

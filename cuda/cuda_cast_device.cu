// The out-of-core CastDevice on CUDA (cache/out_of_core/cast_device.h has the protocol;
// SimulatedCastDevice is its CPU stand-in, which the tests run). Device memory: the page table mirrored
// word for word (directory + page pool), the brick slot pool (linear, read by cache/virtual_sampler.h's
// SlotSampler — or a 3D texture atlas), per-slot usage stamps and the de-duplicating miss buffer
// (cache/miss_buffer.h's CUDA branch: atomicCAS into an open-addressing table). New bricks go up on a
// copy stream from pinned staging while the frame's kernel runs on the compute stream; begin_frame()
// waits for them.
#include <cuda_runtime.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>
#include <vector>

#include "cache/out_of_core/cast_device.h"
#include "core/util/error.h"
#include "cuda/cast_kernels.cuh"
#include "cuda/cuda_renderer.h"
#include "cuda/device_samplers.cuh"

namespace sl::cuda {
namespace {

__global__ void scatter_words(std::uint32_t* dst, const std::uint64_t* index, const std::uint32_t* value,
                              std::uint32_t n) {
  const std::uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) dst[index[i]] = value[i];
}

std::uint64_t round_up(std::uint64_t n, std::uint64_t a) { return (n + a - 1) / a * a; }

class CudaCastDevice final : public CastDevice {
 public:
  explicit CudaCastDevice(const CastDeviceOptions& o) : options_(o) {
    check(cudaStreamCreateWithFlags(&compute_, cudaStreamNonBlocking), "cudaStreamCreate");
    check(cudaStreamCreateWithFlags(&copy_, cudaStreamNonBlocking), "cudaStreamCreate");
  }
  ~CudaCastDevice() override {
    if (atlas_tex_) check_noexcept(cudaDestroyTextureObject(atlas_tex_), "cudaDestroyTextureObject");
    if (atlas_) check_noexcept(cudaFreeArray(atlas_), "cudaFreeArray");
    check_noexcept(cudaStreamDestroy(compute_), "cudaStreamDestroy");
    check_noexcept(cudaStreamDestroy(copy_), "cudaStreamDestroy");
  }

  const char* name() const override { return "cuda"; }
  bool shares_host_memory() const override { return false; }

  void configure(const DeviceConfig& c) override {
    config_ = c;
    const std::uint64_t n = c.layout.stored_voxels();
    voxel_bytes_ = n * std::uint64_t(voxel_size(c.voxel_type));
    label_bytes_ = c.has_labels ? n * std::uint64_t(voxel_size(c.label_type)) : 0;
    voxel_stride_ = round_up(voxel_bytes_, 256);
    label_stride_ = round_up(label_bytes_, 256);
    layout_.upload(&c.layout, 1, compute_);
    use_atlas_ = options_.texture_atlas && c.voxel_type != VoxelType::U32;
    if (use_atlas_) {
      make_atlas();
    } else {
      voxels_.reserve(std::size_t(voxel_stride_ * c.slot_count));
    }
    if (label_stride_) labels_.reserve(std::size_t(label_stride_ * c.slot_count));
    usage_.reserve(c.slot_count);
    check(cudaMemsetAsync(usage_.get(), 0, c.slot_count * sizeof(std::uint32_t), compute_), "cudaMemset");
    directory_.reserve(std::max<std::size_t>(c.directory_words, 1));
    check(cudaMemsetAsync(directory_.get(), 0, directory_.capacity() * sizeof(std::uint32_t), compute_), "cudaMemset");
    pool_words_ = 0;
    table_size_ = std::bit_ceil(2u * c.miss_capacity);
    miss_table_.reserve(table_size_);
    miss_list_.reserve(c.miss_capacity);
    miss_counters_.reserve(2);
    shortfall_.reserve(SampleShortfall::kWords);
    in_flight_.assign(c.slot_count, false);
    held_.clear();
    usage_host_.resize(c.slot_count);
    check(cudaStreamSynchronize(compute_), "configure");
  }

  void begin_frame() override {
    // The copy stream of last frame's uploads has drained; the words held for those slots apply now.
    check(cudaStreamSynchronize(copy_), "brick uploads");
    std::fill(in_flight_.begin(), in_flight_.end(), false);
    apply(held_);
    held_.clear();
  }

  void upload_bricks(std::span<const BrickUpload> bricks) override {
    if (bricks.empty()) return;
    std::size_t total = 0;
    for (const BrickUpload& b : bricks) total += b.voxels.size() + b.labels.size();
    staging_.reserve(total);  // free: begin_frame drained the stream that last read it
    std::byte* dst = staging_.get();
    for (const BrickUpload& b : bricks) {
      SL_CHECK(b.slot < config_.slot_count && b.voxels.size() == voxel_bytes_);
      std::memcpy(dst, b.voxels.data(), b.voxels.size());
      if (use_atlas_) {
        copy_to_atlas(b.slot, dst);
      } else {
        check(cudaMemcpyAsync(voxels_.get() + b.slot * voxel_stride_, dst, voxel_bytes_, cudaMemcpyHostToDevice, copy_),
              "brick upload");
      }
      dst += b.voxels.size();
      if (label_stride_ && !b.labels.empty()) {
        SL_CHECK(b.labels.size() == label_bytes_);
        std::memcpy(dst, b.labels.data(), b.labels.size());
        check(cudaMemcpyAsync(labels_.get() + b.slot * label_stride_, dst, label_bytes_, cudaMemcpyHostToDevice, copy_),
              "label upload");
        dst += b.labels.size();
      }
      in_flight_[b.slot] = true;
    }
  }

  void sync_page_table(const PageTableUpdate& update) override {
    PageTableUpdate now;
    split_page_table_update(update, in_flight_, now, held_);
    apply(now);
  }

  void cast(const CastRequest& r, Frame& frame, CastFeedback& fb) override {
    Timer timer;
    check(cudaMemsetAsync(miss_table_.get(), 0, table_size_ * sizeof(std::uint64_t), compute_), "cudaMemset");
    check(cudaMemsetAsync(miss_counters_.get(), 0, 2 * sizeof(std::uint32_t), compute_), "cudaMemset");
    check(cudaMemsetAsync(shortfall_.get(), 0, SampleShortfall::kWords * sizeof(std::uint64_t), compute_), "cudaMemset");
    CastParams p = r.params;
    SkipInputs skip = r.skip;
    inputs_.upload(p, skip, compute_);  // transfer-function table, enabled labels, segment lists
    const bool depth = writes_depth(p.mode);
    const FrameOutputs out = frame_.prepare(r.gen.width, r.gen.height, depth, compute_);
    dispatch_voxel(config_.voxel_type, [&](auto tag) { launch<decltype(tag)>(r, p, skip, out); });
    frame_.finish(frame, skip.method, depth, compute_);  // synchronises the compute stream
    // Copied back once per frame: the miss list, the usage stamps and the shortfall counters.
    std::uint32_t claimed = 0;  // ids claimed (may exceed the capacity: the rest were dropped)
    miss_counters_.download(&claimed, 1, compute_);
    check(cudaStreamSynchronize(compute_), "miss counters");
    const std::uint32_t n = std::min(claimed, config_.miss_capacity);
    std::vector<std::uint64_t> ids(n);
    miss_list_.download(ids.data(), n, compute_);
    usage_.download(usage_host_.data(), config_.slot_count, compute_);
    shortfall_.download(shortfall_host_.data(), SampleShortfall::kWords, compute_);
    check(cudaStreamSynchronize(compute_), "miss, usage and shortfall copy-back");
    add_shortfall(r.host.shortfall, shortfall_host_);
    fb.misses.resize(n);
    for (std::uint32_t i = 0; i < n; ++i) fb.misses[i].bits = ids[i];
    std::sort(fb.misses.begin(), fb.misses.end());
    fb.used_slots.clear();
    for (std::uint32_t s = 0; s < config_.slot_count; ++s) {
      if (usage_host_[s] == r.frame) fb.used_slots.push_back(s);
    }
    frame.stats.time_ms.raycast = timer.ms();
    frame.stats.backend = "cuda";
  }

 private:
  void make_atlas() {
    int dev = 0;
    check(cudaGetDevice(&dev), "cudaGetDevice");
    cudaDeviceProp prop{};
    check(cudaGetDeviceProperties(&prop, dev), "cudaGetDeviceProperties");
    const int S = config_.layout.stored_size();
    const int per_axis = std::max(1, std::min(prop.maxTexture3D[0], prop.maxTexture3D[1]) / S);
    const std::uint32_t slots = config_.slot_count;
    cells_.x = int(std::min<std::uint32_t>(slots, std::uint32_t(per_axis)));
    cells_.y = int(std::min<std::uint32_t>((slots + cells_.x - 1) / cells_.x, std::uint32_t(per_axis)));
    cells_.z = int((slots + std::uint32_t(cells_.x * cells_.y) - 1) / std::uint32_t(cells_.x * cells_.y));
    if (cells_.z * S > prop.maxTexture3D[2]) {
      throw InputError("--cache-mb", "the brick cache does not fit one 3D texture on this GPU; use a smaller budget");
    }
    cudaChannelFormatDesc desc{};
    cudaTextureDesc td{};
    switch (config_.voxel_type) {
      case VoxelType::U8:
        desc = cudaCreateChannelDesc<unsigned char>();
        td.readMode = cudaReadModeNormalizedFloat;
        scale_ = 255.0f;
        break;
      case VoxelType::U16:
        desc = cudaCreateChannelDesc<unsigned short>();
        td.readMode = cudaReadModeNormalizedFloat;
        scale_ = 65535.0f;
        break;
      default:
        desc = cudaCreateChannelDesc<float>();
        td.readMode = cudaReadModeElementType;
        scale_ = 1.0f;
        break;
    }
    check(cudaMalloc3DArray(&atlas_, &desc, make_cudaExtent(cells_.x * S, cells_.y * S, cells_.z * S)),
          "cudaMalloc3DArray");
    cudaResourceDesc res{};
    res.resType = cudaResourceTypeArray;
    res.res.array.array = atlas_;
    td.addressMode[0] = td.addressMode[1] = td.addressMode[2] = cudaAddressModeClamp;
    td.filterMode = cudaFilterModeLinear;  // hardware trilinear inside a slot: the apron supplies neighbours
    td.normalizedCoords = 0;
    check(cudaCreateTextureObject(&atlas_tex_, &res, &td, nullptr), "cudaCreateTextureObject");
  }

  void copy_to_atlas(std::uint32_t slot, const std::byte* src) {
    const int S = config_.layout.stored_size();
    const std::size_t vs = std::size_t(voxel_size(config_.voxel_type));
    cudaMemcpy3DParms m{};
    m.srcPtr = make_cudaPitchedPtr(const_cast<std::byte*>(src), std::size_t(S) * vs, std::size_t(S), std::size_t(S));
    m.dstArray = atlas_;
    m.dstPos = make_cudaPos(std::size_t(slot % std::uint32_t(cells_.x)) * S,
                            std::size_t((slot / std::uint32_t(cells_.x)) % std::uint32_t(cells_.y)) * S,
                            std::size_t(slot / std::uint32_t(cells_.x * cells_.y)) * S);
    m.extent = make_cudaExtent(std::size_t(S), std::size_t(S), std::size_t(S));
    m.kind = cudaMemcpyHostToDevice;
    check(cudaMemcpy3DAsync(&m, copy_), "cudaMemcpy3DAsync");
  }

  // Scatters the words of `u` into the device page table (compute stream, so before the next cast).
  void apply(const PageTableUpdate& u) {
    if (u.empty()) return;
    const std::uint64_t need = u.pool_words_needed();
    if (need > pool_words_) {
      pool_.reserve(std::size_t(round_up(need, kChunkWords)), /*keep=*/true, compute_);
      pool_words_ = pool_.capacity();
    }
    scatter(directory_.get(), std::vector<std::uint64_t>(u.dir_index.begin(), u.dir_index.end()), u.dir_value);
    scatter(pool_.get(), u.pool_index, u.pool_value);
  }
  void scatter(std::uint32_t* dst, const std::vector<std::uint64_t>& index, const std::vector<std::uint32_t>& value) {
    if (index.empty()) return;
    const std::uint32_t n = std::uint32_t(index.size());
    scatter_index_.upload(index.data(), n, compute_);
    scatter_value_.upload(value.data(), n, compute_);
    scatter_words<<<(n + 255) / 256, 256, 0, compute_>>>(dst, scatter_index_.get(), scatter_value_.get(), n);
    check(cudaGetLastError(), "scatter_words");
    // The next scatter reuses the index/value buffers: keep the order simple.
    check(cudaStreamSynchronize(compute_), "page-table sync");
  }

  template <class T>
  void launch(const CastRequest& r, const CastParams& p, const SkipInputs& skip, const FrameOutputs& out) {
    VirtualAnyLabelSampler<T> s;
    s.v.layout = layout_.get();
    s.v.page_table = config_.page_table_geometry;
    s.v.page_table.directory = directory_.get();
    s.v.page_table.pool = pool_.get();
    s.v.cache = device_cache_view(config_, use_atlas_ ? nullptr : voxels_.get(), labels_.get(), usage_.get(),
                                  voxel_stride_, label_stride_);
    MissBufferView& m = s.v.misses;
    m.table = miss_table_.get();
    m.list = miss_list_.get();
    m.counters = miss_counters_.get();
    m.table_mask = table_size_ - 1;
    m.capacity = config_.miss_capacity;
    s.v.frame = r.frame;
    s.v.has_labels = config_.has_labels;
    s.v.shortfall = r.host.shortfall;  // the frame's level of detail; counted in device memory
    s.v.shortfall.counters = r.host.shortfall.counters ? shortfall_.get() : nullptr;
    s.label_type = config_.label_type;
    if constexpr (!std::is_same_v<T, std::uint32_t>) {
      if (use_atlas_) {
        TextureVirtualSampler<T> t{s, atlas_tex_, cells_, scale_};
        launch_cast<TextureVirtualSampler<T>, false>(skip.method, RayCaster<TextureVirtualSampler<T>>{p, t}, r.gen,
                                                     r.vbox, skip, out, compute_);
        return;
      }
    }
    launch_cast<VirtualAnyLabelSampler<T>, false>(skip.method, RayCaster<VirtualAnyLabelSampler<T>>{p, s}, r.gen,
                                                  r.vbox, skip, out, compute_);
  }

  CastDeviceOptions options_;
  DeviceConfig config_{};
  cudaStream_t compute_ = nullptr, copy_ = nullptr;
  std::uint64_t voxel_bytes_ = 0, label_bytes_ = 0, voxel_stride_ = 0, label_stride_ = 0;
  bool use_atlas_ = false;
  cudaArray_t atlas_ = nullptr;
  cudaTextureObject_t atlas_tex_ = 0;
  ivec3 cells_{1};
  float scale_ = 1.0f;
  DeviceBuffer<BrickLayout> layout_;
  DeviceBuffer<std::byte> voxels_, labels_;
  DeviceBuffer<std::uint32_t> usage_, directory_, pool_, miss_counters_, scatter_value_;
  DeviceBuffer<std::uint64_t> miss_table_, miss_list_, scatter_index_, shortfall_;
  std::array<std::uint64_t, SampleShortfall::kWords> shortfall_host_{};
  FrameInputs inputs_;
  std::uint64_t pool_words_ = 0;
  std::uint32_t table_size_ = 0;
  PinnedBuffer staging_;
  std::vector<bool> in_flight_;
  PageTableUpdate held_;
  std::vector<std::uint32_t> usage_host_;
  DeviceFrame frame_;
};

}  // namespace

std::unique_ptr<CastDevice> make_cast_device(const CastDeviceOptions& options) {
  return std::make_unique<CudaCastDevice>(options);
}

}  // namespace sl::cuda

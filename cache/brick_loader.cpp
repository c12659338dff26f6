#include "cache/brick_loader.h"

#include <algorithm>
#include <exception>

#include "core/config.h"
#include "core/error.h"

namespace sl {

BrickLoader::BrickLoader(std::shared_ptr<const VolumeSource> source, const BrickLayout& layout, int threads)
    : source_(std::move(source)), layout_(layout) {
  SL_CHECK(source_ != nullptr);
  if (threads <= 0) threads = int(std::clamp(std::thread::hardware_concurrency(), 1u, 4u));
  workers_.reserve(std::size_t(threads));
  for (int i = 0; i < threads; ++i) workers_.emplace_back([this] { work(); });
}

BrickLoader::~BrickLoader() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
    queue_.clear();
  }
  wake_.notify_all();
  for (std::thread& t : workers_) t.join();
}

std::size_t BrickLoader::request(std::span<const BrickId> ids) {
  std::size_t queued = 0;
  {
    std::lock_guard lock(mutex_);
    for (const BrickId id : ids) {
      SL_CHECK(layout_.contains(id));
      if (failed_.count(id) || !known_.insert(id).second) continue;
      queue_.push_back({next_seq_++, id});
      ++queued;
    }
  }
  if (queued == 1) {
    wake_.notify_one();
  } else if (queued > 1) {
    wake_.notify_all();
  }
  return queued;
}

LoaderBatch BrickLoader::collect(std::size_t max_bricks) {
  LoaderBatch batch;
  std::lock_guard lock(mutex_);
  batch.failures.swap(new_failures_);
  const std::size_t n = std::min(max_bricks, done_.size());
  if (n == 0) return batch;
  // Oldest requests first: the renderer requests in priority order.
  std::partial_sort(done_.begin(), done_.begin() + std::ptrdiff_t(n), done_.end(),
                    [](const Done& a, const Done& b) { return a.seq < b.seq; });
  batch.bricks.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    known_.erase(done_[i].brick.id);
    batch.bricks.push_back(std::move(done_[i].brick));
  }
  done_.erase(done_.begin(), done_.begin() + std::ptrdiff_t(n));
  return batch;
}

std::size_t BrickLoader::cancel_queued() {
  std::lock_guard lock(mutex_);
  const std::size_t n = queue_.size();
  for (const Job& j : queue_) known_.erase(j.id);
  queue_.clear();
  if (loading_ == 0) idle_.notify_all();
  return n;
}

void BrickLoader::recycle(LoadedBrick&& brick) {
  std::lock_guard lock(mutex_);
  if (spare_.size() < 2 * workers_.size() + 16) spare_.push_back(std::move(brick));
}

bool BrickLoader::failed(BrickId id) const {
  std::lock_guard lock(mutex_);
  return failed_.count(id) != 0;
}

std::size_t BrickLoader::failed_count() const {
  std::lock_guard lock(mutex_);
  return failed_.size();
}

std::size_t BrickLoader::pending() const {
  std::lock_guard lock(mutex_);
  return queue_.size() + loading_ + done_.size();
}

std::uint64_t BrickLoader::loads_completed() const {
  std::lock_guard lock(mutex_);
  return completed_;
}

void BrickLoader::wait_idle() {
  std::unique_lock lock(mutex_);
  idle_.wait(lock, [&] { return queue_.empty() && loading_ == 0; });
}

void BrickLoader::work() {
  const std::size_t n = layout_.stored_voxels();
  const std::size_t intensity_bytes = n * std::size_t(voxel_size(source_->desc().type));
  const std::size_t label_bytes = source_->has_labels() ? n * std::size_t(voxel_size(source_->label_type())) : 0;
  std::unique_lock lock(mutex_);
  for (;;) {
    wake_.wait(lock, [&] { return stop_ || !queue_.empty(); });
    if (stop_) return;
    const Job job = queue_.front();
    queue_.pop_front();
    ++loading_;
    LoadedBrick brick;
    if (!spare_.empty()) {
      brick = std::move(spare_.back());
      spare_.pop_back();
    }
    lock.unlock();

    brick.id = job.id;
    brick.intensity.resize(intensity_bytes);
    brick.labels.resize(label_bytes);
    std::string error;
    try {
      source_->read_brick(layout_, job.id, brick.intensity, brick.labels);
    } catch (const InputError& e) {
      error = e.reason();  // the source's name is prefixed below
    } catch (const std::exception& e) {
      error = e.what();
      if (error.empty()) error = "unknown error";
    } catch (...) {
      error = "unknown error";
    }

    lock.lock();
    --loading_;
    ++completed_;
    if (!error.empty()) {
      // Reported once through collect(), remembered so the brick is never requested again.
      known_.erase(job.id);
      failed_.emplace(job.id, error);
      new_failures_.push_back({job.id, source_->name() + ": " + to_string(job.id) + ": " + error, error});
    } else {
      done_.push_back({job.seq, std::move(brick)});
    }
    if (queue_.empty() && loading_ == 0) idle_.notify_all();
  }
}

}  // namespace sl

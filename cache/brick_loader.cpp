#include "cache/brick_loader.h"

#include <algorithm>
#include <exception>

#include "core/util/config.h"
#include "core/util/error.h"

namespace sl {

namespace {

// Orders the backoff heap so that its front is the earliest due retry.
template <class R>
bool later(const R& a, const R& b) {
  return a.due > b.due;
}

}  // namespace

std::chrono::milliseconds RetryPolicy::backoff(int attempt) const {
  std::chrono::milliseconds b = first_backoff;
  for (int i = 0; i < attempt && b < max_backoff; ++i) b *= 2;
  return std::min(b, max_backoff);
}

BrickLoader::BrickLoader(std::shared_ptr<const VolumeSource> source, const BrickLayout& layout, int threads,
                         const RetryPolicy& retry, std::size_t finished_bytes, int bounds_block)
    : source_(std::move(source)), layout_(layout), retry_(retry), bounds_block_(bounds_block) {
  SL_CHECK(source_ != nullptr);
  SL_CHECK(retry_.max_attempts >= 1 && retry_.first_backoff.count() >= 0 && retry_.max_backoff >= retry_.first_backoff);
  if (threads <= 0) threads = int(std::clamp(std::thread::hardware_concurrency(), 1u, 4u));
  const std::size_t n = layout_.stored_voxels();
  const std::size_t brick_bytes = n * std::size_t(voxel_size(source_->desc().type)) +
                                  (source_->has_labels() ? n * std::size_t(voxel_size(source_->label_type())) : 0);
  finished_cap_ = std::max(std::size_t(threads), finished_bytes / std::max<std::size_t>(brick_bytes, 1));
  workers_.reserve(std::size_t(threads));
  for (int i = 0; i < threads; ++i) workers_.emplace_back([this] { work(); });
}

BrickLoader::~BrickLoader() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
    queue_.clear();
    prefetch_queue_.clear();
    backoff_.clear();  // workers waiting for a retry's due time wake at the notify below
  }
  wake_.notify_all();
  for (std::thread& t : workers_) t.join();
}

// The latest request's order is the loader's: its ids, new or already queued, go ahead of every job
// queued before, in the order given (the renderer's priority for the frame it just cast), so a brick
// an earlier view wanted never delays one the present view wants. Jobs it does not name keep their
// order behind (never dropped: a metadata load may be asked for once only).
std::size_t BrickLoader::request(std::span<const BrickId> ids) {
  std::size_t queued = 0;
  {
    std::lock_guard lock(mutex_);
    std::unordered_set<BrickId, BrickIdHash> again;  // named and queued before (request or prefetch)
    for (const BrickId id : ids) {
      SL_CHECK(layout_.contains(id));
      if (!failed_.count(id) && known_.count(id)) again.insert(id);
    }
    std::unordered_map<BrickId, Job, BrickIdHash> waiting;  // the queued jobs named again, taken out
    const auto take = [&](std::deque<Job>& q) {
      if (again.empty()) return;
      std::erase_if(q, [&](const Job& j) { return again.count(j.id) && waiting.emplace(j.id, j).second; });
    };
    take(queue_);
    const std::size_t from_requests = waiting.size();
    take(prefetch_queue_);
    queued += waiting.size() - from_requests;  // a prefetch becomes a request
    std::deque<Job> front;
    for (const BrickId id : ids) {
      if (failed_.count(id)) continue;
      if (known_.insert(id).second) {
        front.push_back({next_seq_++, id});
        ++queued;
      } else if (const auto it = waiting.find(id); it != waiting.end()) {
        Job j = it->second;
        j.seq = next_seq_++;  // collect hands bricks out in this order too
        front.push_back(j);
        waiting.erase(it);
      }
    }
    if (!front.empty() && !queue_.empty()) {
      for (Job& j : queue_) j.seq = next_seq_++;  // behind the front: collect follows the queue's order
    }
    queue_.insert(queue_.begin(), front.begin(), front.end());
  }
  if (queued == 1) {
    wake_.notify_one();
  } else if (queued > 1) {
    wake_.notify_all();
  }
  return queued;
}

std::size_t BrickLoader::prefetch(std::span<const BrickId> ids) {
  std::size_t queued = 0;
  {
    std::lock_guard lock(mutex_);
    for (const BrickId id : ids) {
      SL_CHECK(layout_.contains(id));
      if (failed_.count(id) || !known_.insert(id).second) continue;
      prefetch_queue_.push_back({next_seq_++, id});
      ++queued;
    }
  }
  if (queued) wake_.notify_all();
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
  wake_.notify_all();  // room under the bound of finished bricks
  return batch;
}

std::size_t BrickLoader::cancel_queued() {
  std::lock_guard lock(mutex_);
  const std::size_t n = queue_.size() + prefetch_queue_.size() + backoff_.size();
  for (const Job& j : queue_) known_.erase(j.id);
  for (const Job& j : prefetch_queue_) known_.erase(j.id);
  for (const Retry& r : backoff_) known_.erase(r.job.id);
  queue_.clear();
  prefetch_queue_.clear();
  backoff_.clear();
  if (settled()) idle_.notify_all();
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
  return queue_.size() + prefetch_queue_.size() + backoff_.size() + loading_ + done_.size();
}

std::uint64_t BrickLoader::loads_completed() const {
  std::lock_guard lock(mutex_);
  return completed_;
}

LoaderCounts BrickLoader::counts() const {
  std::lock_guard lock(mutex_);
  LoaderCounts c = counts_;
  c.failed = failed_.size();
  return c;
}

void BrickLoader::wait_idle() {
  std::unique_lock lock(mutex_);
  idle_.wait(lock, [&] { return settled(); });
}

void BrickLoader::promote_due_retries(Clock::time_point now) {
  while (!backoff_.empty() && backoff_.front().due <= now) {
    std::pop_heap(backoff_.begin(), backoff_.end(), later<Retry>);
    queue_.push_front(backoff_.back().job);
    backoff_.pop_back();
  }
}

void BrickLoader::work() {
  const std::size_t n = layout_.stored_voxels();
  const std::size_t intensity_bytes = n * std::size_t(voxel_size(source_->desc().type));
  const std::size_t label_bytes = source_->has_labels() ? n * std::size_t(voxel_size(source_->label_type())) : 0;
  std::unique_lock lock(mutex_);
  for (;;) {
    // Idle workers wait for a request or for the earliest retry's due time; no worker ever sleeps
    // through a backoff while other bricks could load.
    for (;;) {
      if (stop_) return;
      promote_due_retries(Clock::now());
      if (full() && (!queue_.empty() || !prefetch_queue_.empty())) {
        wake_.wait(lock);  // until collect() takes finished bricks (or the loader stops)
        continue;
      }
      if (!queue_.empty()) break;
      if (!prefetch_queue_.empty()) {  // only when no request waits
        queue_.push_back(prefetch_queue_.front());
        prefetch_queue_.pop_front();
        break;
      }
      if (backoff_.empty()) {
        wake_.wait(lock);
      } else {
        // A copy: wait_until reads its deadline again after waking, when another worker may have
        // reallocated backoff_ while the lock was released (a reference would dangle).
        const Clock::time_point due = backoff_.front().due;
        wake_.wait_until(lock, due);
      }
    }
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
    bool transient = false;
    try {
      brick.bounds.clear();
      if (bounds_block_ > 0 && job.id.level() > 0) {
        source_->read_brick_bounded(layout_, job.id, brick.intensity, brick.labels, bounds_block_, brick.bounds);
      } else {
        source_->read_brick(layout_, job.id, brick.intensity, brick.labels);
      }
    } catch (const TransientError& e) {
      error = e.reason();
      transient = true;
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
    if (transient && job.attempt + 1 < retry_.max_attempts && !stop_) {
      // Retried later, when a worker is free after the backoff; the buffers (possibly half filled by
      // a short read) are dropped, never handed out.
      if (job.attempt == 0) ++counts_.bricks_retried;
      ++counts_.retries;
      backoff_.push_back({Clock::now() + retry_.backoff(job.attempt), job});
      ++backoff_.back().job.attempt;
      std::push_heap(backoff_.begin(), backoff_.end(), later<Retry>);
      wake_.notify_all();  // idle workers now wait for its due time
      continue;
    }
    if (transient && job.attempt > 0) error += " (still failing after " + std::to_string(job.attempt + 1) + " attempts)";
    if (!error.empty()) {
      // Reported once through collect(), remembered so the brick is never requested again.
      known_.erase(job.id);
      failed_.emplace(job.id, error);
      new_failures_.push_back({job.id, source_->name() + ": " + to_string(job.id) + ": " + error, error});
    } else {
      if (job.attempt > 0) ++counts_.recovered;
      done_.push_back({job.seq, std::move(brick)});
    }
    if (settled()) idle_.notify_all();
  }
}

}  // namespace sl

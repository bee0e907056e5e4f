// src/batch/engine/pool.hpp — the engine's persistent thread pool (private to
// src/engine*.cpp).
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <thread>
#include <vector>

namespace rbd {
namespace engine_detail {

// ---- persistent pool of n - 1 workers. run() publishes a job and works on
// it as thread 0; each worker t < active that arrives before the caller has
// finished and closed the job works on it too, so a late worker (asleep,
// or its core busy) delays nothing. The job hands out its work itself (a
// share per thread, the others' taken once one's own is done: Job::claim),
// so whichever threads come share it.
//
// Between jobs a worker spins on the state word for up to kSpin (a pause
// instruction per try), then sleeps on a condition variable; the caller
// waits for the workers inside its job the same way. A call while the
// workers spin costs two cache-line transfers each way and no system call.
class Pool {
 public:
  explicit Pool(int n) {
    for (int t = 1; t < n; ++t) workers_.emplace_back([this, t] { loop(t); });
  }
  ~Pool() {
    stop_.store(true);
    { std::lock_guard<std::mutex> lk(mu_); }  // a worker between its check and its wait is waiting now
    start_.notify_all();
    for (std::thread& th : workers_) th.join();
  }
  // fn(ctx, t) on threads 0 (the caller) .. active - 1; fn must not throw
  void run(int active, void (*fn)(void*, int), void* ctx) {
    active = std::min<int>(active, static_cast<int>(workers_.size()) + 1);
    if (active <= 1) {
      fn(ctx, 0);
      return;
    }
    fn_ = fn, ctx_ = ctx;
    // publish (no worker is inside: the last job was closed and left)
    const std::uint64_t e = (epoch(state_.load(std::memory_order_relaxed)) + 1u) & 0xffffffffu;
    state_.store(e << 32 | std::uint64_t(active) << 16 | kOpen);
    if (sleeping_.load() > 0) {
      { std::lock_guard<std::mutex> lk(mu_); }
      start_.notify_all();
    }
    fn(ctx, 0);
    // close: no worker joins from here on; wait for those inside
    if ((state_.fetch_and(~kOpen) & kInside) == 0) return;
    if (spin([this] { return (state_.load(std::memory_order_acquire) & kInside) == 0; })) return;
    std::unique_lock<std::mutex> lk(mu_);
    caller_sleeping_.store(true);
    done_.wait(lk, [this] { return (state_.load() & kInside) == 0; });
    caller_sleeping_.store(false, std::memory_order_relaxed);
  }

 private:
  // state_: epoch (bits 32..63, +1 per job), active (16..31), open (15: workers may join), inside (0..14)
  static constexpr std::uint64_t kOpen = 1u << 15, kInside = kOpen - 1;
  static constexpr std::chrono::microseconds kSpin{50};
  static std::uint32_t epoch(std::uint64_t s) { return static_cast<std::uint32_t>(s >> 32); }
  static int active(std::uint64_t s) { return static_cast<int>((s >> 16) & 0xffffu); }

  static void cpu_relax() {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#elif defined(__aarch64__)
    __asm__ __volatile__("yield");
#endif
  }
  // true once ready() holds, false if it did not within kSpin
  template <typename F> static bool spin(F ready) {
    const auto until = std::chrono::steady_clock::now() + kSpin;
    for (unsigned i = 1;; ++i) {
      if (ready()) return true;
      cpu_relax();
      if (i % 64 == 0 && std::chrono::steady_clock::now() >= until) return ready();
    }
  }

  void loop(int t) {
    std::uint32_t seen = 0;
    for (;;) {
      std::uint64_t s = state_.load(std::memory_order_acquire);
      if (epoch(s) == seen) {  // wait for the next job: spin, then sleep
        auto next = [&] {
          s = state_.load();
          return stop_.load(std::memory_order_relaxed) || epoch(s) != seen;
        };
        if (!spin(next)) {
          std::unique_lock<std::mutex> lk(mu_);
          sleeping_.fetch_add(1);
          start_.wait(lk, next);
          sleeping_.fetch_sub(1);
        }
        if (stop_.load()) return;
      }
      seen = epoch(s);
      // join while the job is open and counts this thread in
      while ((s & kOpen) && t < active(s) && epoch(s) == seen)
        if (state_.compare_exchange_weak(s, s + 1)) {
          fn_(ctx_, t);
          const std::uint64_t before = state_.fetch_sub(1);
          if ((before & kInside) == 1 && !(before & kOpen) && caller_sleeping_.load()) {
            { std::lock_guard<std::mutex> lk(mu_); }
            done_.notify_one();
          }
          break;
        }
    }
  }

  std::vector<std::thread> workers_;
  alignas(64) std::atomic<std::uint64_t> state_{0};
  std::atomic<int> sleeping_{0};      // workers asleep on start_
  std::atomic<bool> caller_sleeping_{false}, stop_{false};
  void (*fn_)(void*, int) = nullptr;  // the job (written before it is published)
  void* ctx_ = nullptr;
  alignas(64) std::mutex mu_;
  std::condition_variable start_, done_;
};

}  // namespace engine_detail
}  // namespace rbd

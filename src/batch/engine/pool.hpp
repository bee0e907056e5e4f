// src/batch/engine/pool.hpp — the engine's persistent thread pool (private to
// src/engine*.cpp).
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace rbd {
namespace engine_detail {

// ---- persistent pool of n - 1 workers running a parallel loop over `units`
// (the engine's packs). run() publishes a job and works on it as thread 0;
// each worker t < active that enters the job before the caller has finished
// and closed it works on it too, so a late worker (asleep, or its core busy)
// delays nothing.
//
// Work: thread t's share is units [t·units/active, (t+1)·units/active), the
// same from call to call (repeated calls on the same arrays find each
// thread's inputs and outputs in its own core's cache). Claims::next hands
// out guided chunks, half of what is left of its own share (at least one),
// then of the others' shares in turn (from their back), so threads that
// start late or run slow still finish together, in O(active · log(units))
// claims.
//
// Hand-off, in cache lines (each transfer between two cores costs about
// 100 ns, which at B = 256 is what a 2-thread call has to save):
//   - go_: written by the caller only: the job word (its epoch e, its
//     thread count, open or closed) and the job. A worker reads it when the
//     epoch moves.
//   - slots_[t]: thread t's line: its entry word (2e: inside job e, 2e + 1:
//     done with it), written by worker t only, and its share's claim word
//     (epoch tag | next unit | end), written by whoever claims from it.
//     A share is reset by the first claim of a job (the tag is stale), so the
//     caller writes no worker's line to publish a job.
// A call while the workers spin costs the epoch line to the worker, the
// worker's line back to the caller, and no system call. Entry and close
// are a store then a load on both sides (sequentially consistent), so either
// the caller sees a worker inside and waits for it, or the worker sees the
// job closed and stays out.
//
// Between jobs a worker spins on go_ for up to kSpin (a pause instruction
// per try), then sleeps on a condition variable; the caller waits for the
// workers inside its job the same way.
class Pool {
 public:
  // a claim word: the job's epoch (low kTagBits bits) | the share's next unit | its end (kUnitBits each)
  static constexpr int kTagBits = 16, kUnitBits = 24;
  static constexpr long kMaxUnits = (1L << kUnitBits) - 1;  // units of one job

 private:
  struct alignas(64) Slot {
    std::atomic<std::uint64_t> entry{1};  // worker t: 2e inside job e, 2e + 1 done with it (epoch 0: done)
    std::atomic<std::uint64_t> claim{0};  // thread t's share [next, end), tagged; a stale tag: the whole share
  };

 public:
  // thread t's claims on one job
  class Claims {
   public:
    // the next units [u0, u1) for this thread; false once every share is taken. From its own share
    // it takes from the front, from another's from the back: the units a thread takes from another
    // are then the same from call to call (the end of a late thread's share), and so are the cache
    // lines of their inputs and outputs
    bool next(long& u0, long& u1) {
      for (int k = 0; k < active_; ++k) {
        const int s = (t_ + k) % active_;
        std::atomic<std::uint64_t>& c = slots_[s].claim;
        std::uint64_t w = c.load(std::memory_order_relaxed);
        for (;;) {
          std::uint64_t next, end;
          if ((w >> (2 * kUnitBits)) == tag_) {
            next = (w >> kUnitBits) & kUnitMask, end = w & kUnitMask;
          } else {  // the first claim on this share in this job
            next = units_ * std::uint64_t(s) / std::uint64_t(active_);
            end = units_ * std::uint64_t(s + 1) / std::uint64_t(active_);
          }
          if (next >= end) break;
          const std::uint64_t n = std::max<std::uint64_t>(1, (end - next) / 2);
          const std::uint64_t a = k == 0 ? next : end - n;
          const std::uint64_t to = k == 0 ? word(next + n, end) : word(next, end - n);
          if (c.compare_exchange_weak(w, to, std::memory_order_relaxed)) {
            u0 = static_cast<long>(a), u1 = static_cast<long>(a + n);
            return true;
          }
        }
      }
      return false;
    }

   private:
    friend class Pool;
    static constexpr std::uint64_t kUnitMask = (std::uint64_t(1) << kUnitBits) - 1;
    static constexpr std::uint64_t kTagMask = (std::uint64_t(1) << kTagBits) - 1;
    Claims(Slot* slots, int t, int active, std::uint64_t units, std::uint64_t epoch)
        : slots_(slots), t_(t), active_(active), units_(units), tag_(epoch & kTagMask) {}
    std::uint64_t word(std::uint64_t next, std::uint64_t end) const {
      return tag_ << (2 * kUnitBits) | next << kUnitBits | end;
    }
    Slot* slots_;
    int t_, active_;
    std::uint64_t units_, tag_;
  };
  using Fn = void (*)(void* ctx, int t, Claims& claims);

  explicit Pool(int n) : slots_(new Slot[std::max(n, 1)]), last_active_(std::max(n, 1), 0) {
    for (int t = 1; t < n; ++t) workers_.emplace_back([this, t] { loop(t); });
  }
  ~Pool() {
    stop_.store(true);
    { std::lock_guard<std::mutex> lk(mu_); }  // a worker between its check and its wait is waiting now
    start_.notify_all();
    for (std::thread& th : workers_) th.join();
  }
  // fn(ctx, t, claims) on threads 0 (the caller) .. active - 1 (at most units), over units
  // (at most kMaxUnits); fn must not throw
  void run(int active, long units, Fn fn, void* ctx) {
    active = static_cast<int>(std::max(1L, std::min({long(active), long(workers_.size()) + 1, units})));
    const std::uint64_t e = ++epoch_;
    // a share untouched for 2^(kTagBits - 1) jobs could carry this job's tag: give it the last one (rare)
    for (int t = 0; t < active; ++t) {
      if (e - last_active_[t] >= (std::uint64_t(1) << (kTagBits - 1)))
        slots_[t].claim.store(((e - 1) & Claims::kTagMask) << (2 * kUnitBits), std::memory_order_relaxed);
      last_active_[t] = e;
    }
    Claims mine(slots_.get(), 0, active, static_cast<std::uint64_t>(units), e);
    if (active == 1) {
      fn(ctx, 0, mine);
      return;
    }
    // publish (every worker of the last job is out of it)
    go_.fn = fn, go_.ctx = ctx, go_.units = static_cast<std::uint64_t>(units);
    // a release store: the caller does not wait for the line to leave the worker's cache. The load
    // of sleeping_ may then pass it, and miss a worker that is just falling asleep: that worker sits
    // this job out (the caller and the others do its share) and wakes for the next one
    go_.word.store(job_word(e, active, false), std::memory_order_release);
    if (sleeping_.load() > 0) {
      { std::lock_guard<std::mutex> lk(mu_); }
      start_.notify_all();
    }
    fn(ctx, 0, mine);
    // wait for the workers inside the job; close it to the others
    bool closed = false;
    for (int t = 1; t < active; ++t) {
      std::atomic<std::uint64_t>& entry = slots_[t].entry;
      std::uint64_t s = entry.load(std::memory_order_acquire);
      if (s < 2 * e) {
        if (!closed) go_.word.store(job_word(e, active, true)), closed = true;
        s = entry.load();
        if (s < 2 * e) continue;  // it sees the job closed
      }
      auto done = [&] { return entry.load(std::memory_order_acquire) == 2 * e + 1; };
      if (s == 2 * e + 1 || spin(done)) continue;
      std::unique_lock<std::mutex> lk(mu_);
      go_.caller_sleeping.store(true);
      done_.wait(lk, done);
      go_.caller_sleeping.store(false, std::memory_order_relaxed);
    }
  }

 private:
  static constexpr std::chrono::microseconds kSpin{50};
  // the job word: epoch << 17 | active << 1 | closed
  static std::uint64_t job_word(std::uint64_t e, int active, bool closed) {
    return e << 17 | std::uint64_t(active) << 1 | (closed ? 1u : 0u);
  }

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
    std::atomic<std::uint64_t>& entry = slots_[t].entry;
    std::uint64_t seen = 0;  // the last job this worker saw
    for (;;) {
      auto moved = [&] { return stop_.load(std::memory_order_relaxed) || (go_.word.load() >> 17) != seen; };
      if (!spin(moved)) {  // spin, then sleep
        std::unique_lock<std::mutex> lk(mu_);
        sleeping_.fetch_add(1);
        start_.wait(lk, moved);
        sleeping_.fetch_sub(1);
      }
      if (stop_.load()) return;
      const std::uint64_t w = go_.word.load(), e = w >> 17;
      const int active = static_cast<int>((w >> 1) & 0xffff);
      seen = e;
      // a job without this thread: the caller does not wait for it, nor may it read the job
      if (t >= active) continue;
      // enter, then work if the job is still open (the caller waits for it then)
      entry.store(2 * e);
      if (go_.word.load() == w && !(w & 1)) {
        Claims c(slots_.get(), t, active, go_.units, e);
        go_.fn(go_.ctx, t, c);
      }
      entry.store(2 * e + 1);
      if (go_.caller_sleeping.load()) {
        { std::lock_guard<std::mutex> lk(mu_); }
        done_.notify_one();
      }
    }
  }

  // the caller's line: the epoch word and the job it publishes
  struct alignas(64) Go {
    std::atomic<std::uint64_t> word{1};  // job_word(epoch, active, closed); epoch 0: closed
    Fn fn = nullptr;                     // the job's, read by the workers it lets in
    void* ctx = nullptr;
    std::uint64_t units = 0;
    std::atomic<bool> caller_sleeping{false};
  } go_;
  std::unique_ptr<Slot[]> slots_;           // (threads)
  std::uint64_t epoch_ = 0;                 // the caller's
  std::vector<std::uint64_t> last_active_;  // (threads): the last job in which thread t had a share (the caller's)
  std::vector<std::thread> workers_;
  alignas(64) std::atomic<int> sleeping_{0};  // workers asleep on start_
  std::atomic<bool> stop_{false};
  alignas(64) std::mutex mu_;
  std::condition_variable start_, done_;
};

}  // namespace engine_detail
}  // namespace rbd

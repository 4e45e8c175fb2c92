#include "core/thread_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace mjsysid {
namespace {

// The cap on threads (kMaxThreads): a request beyond it is refused with a reason, 0..256 accepted;
// ThreadCount, and so the pool, never exceeds it whatever it is asked (the pool of a caller that
// skipped the check starts kMaxThreads, not a million)
TEST(ThreadPoolTest, ThreadsAreCapped) {
  EXPECT_EQ(ThreadRequestError(0), "");
  EXPECT_EQ(ThreadRequestError(kMaxThreads), "");
  EXPECT_NE(ThreadRequestError(kMaxThreads + 1).find("from 1 to 256"), std::string::npos);
  EXPECT_NE(ThreadRequestError(-1), "");
  EXPECT_NE(ThreadRequestError(1000000).find("got 1000000"), std::string::npos);
  EXPECT_EQ(ThreadCount(1000000), kMaxThreads);
  EXPECT_EQ(ThreadCount(7), 7);
  EXPECT_GE(ThreadCount(0), 1);
  EXPECT_LE(ThreadCount(0), kMaxThreads);
  ThreadPool pool(1000000);
  EXPECT_EQ(pool.size(), kMaxThreads);
  std::atomic<int> sum{0};
  pool.ParallelFor(1000, [&](int, int i) { sum += i; });
  EXPECT_EQ(sum.load(), 999 * 1000 / 2);
}

TEST(ThreadPoolTest, EveryIndexRunsExactlyOnce) {
  for (int threads : {1, 2, 4}) {
    ThreadPool pool(threads);
    EXPECT_EQ(pool.size(), threads);
    for (int n : {0, 1, 7, 1000}) {
      std::vector<std::atomic<int>> hits(n);
      std::atomic<int> bad_worker{0};
      pool.ParallelFor(n, [&](int worker, int i) {
        if (worker < 0 || worker >= threads) ++bad_worker;
        ++hits[i];
      });
      for (int i = 0; i < n; ++i) ASSERT_EQ(hits[i].load(), 1) << "n=" << n << " i=" << i;
      EXPECT_EQ(bad_worker.load(), 0);
    }
  }
}

TEST(ThreadPoolTest, ExceptionPropagatesAndPoolStaysUsable) {
  ThreadPool pool(3);
  EXPECT_THROW(pool.ParallelFor(100,
                                [](int, int i) {
                                  if (i == 37) throw std::runtime_error("boom");
                                }),
               std::runtime_error);
  std::atomic<int> count{0};
  pool.ParallelFor(50, [&](int, int) { ++count; });
  EXPECT_EQ(count.load(), 50);
}

// the pool's scheduling in the model: tasks in index order, each to the worker free first; a
// follower ends no earlier than the task it trails
TEST(ThreadPoolTest, ListScheduleMakespan) {
  EXPECT_EQ(ListScheduleMakespan({}, {}, 2), 0);
  EXPECT_EQ(ListScheduleMakespan({5, 10}, {}, 1), 15);
  // 3 equal tasks on 2 workers: 2 rounds for 1.5 of work; 4: 2 rounds
  EXPECT_EQ(ListScheduleMakespan({10, 10, 10}, {}, 2), 20);
  EXPECT_EQ(ListScheduleMakespan({10, 10, 10, 10}, {}, 2), 20);
  // index order, not longest first: 1, 1, 10 on 2 workers ends at 11 (longest first: 10)
  EXPECT_EQ(ListScheduleMakespan({1, 1, 10}, {}, 2), 11);
  // a 3-step follower of a 10-step task on the other worker waits for it
  EXPECT_EQ(ListScheduleMakespan({10, 3}, {-1, 0}, 2), 10);
  EXPECT_EQ(ListScheduleMakespan({10, 10, 3}, {-1, -1, 0}, 2), 13);
  // more workers than tasks: the longest task
  EXPECT_EQ(ListScheduleMakespan({4, 7, 2}, {}, 4), 7);
  // continuations start after the task they continue: 3 rollouts in 2 pieces on 2 workers, and a
  // continuation whose worker waits for it
  EXPECT_EQ(ListScheduleMakespan({5, 5, 5, 5, 5, 5}, {}, 2, {-1, -1, -1, 0, 1, 2}), 15);
  EXPECT_EQ(ListScheduleMakespan({10, 1, 5}, {}, 2, {-1, -1, 0}), 15);
  EXPECT_EQ(ListScheduleMakespan({10, 1, 5}, {}, 2), 10);
}

// a metered pool records every task's cost (the growth of its worker's counter) and the batch's
// work and makespans, the same for any thread count
TEST(ThreadPoolTest, MeterRecordsWorkAndMakespans) {
  const std::vector<long long> cost = {3, 1, 4, 1, 5, 9, 2};
  const long long work = 25;
  for (int threads : {1, 2, 3}) {
    ThreadPool pool(threads);
    std::vector<long long> counter(threads, 0);  // each slot advanced by its own worker only
    pool.SetMeter([&](int worker) { return counter[worker]; });
    pool.ParallelFor(static_cast<int>(cost.size()),
                     [&](int worker, int i) { counter[worker] += cost[i]; });
    pool.ParallelFor(1, [&](int worker, int) { counter[worker] += 10; });
    const PoolLoad& load = pool.load();
    EXPECT_EQ(load.batches, 2) << threads;
    EXPECT_EQ(load.work, work + 10) << threads;
    EXPECT_EQ(load.span[1], work + 10) << threads;
    // 2 workers: 3|1, 4 (t=1..5), 1 (t=3..4), 5 (4..9), 9 (5..14), 2 (9..11): 14, then 10
    EXPECT_EQ(load.span[2], 14 + 10) << threads;
    EXPECT_EQ(load.span[2], ListScheduleMakespan(cost, {}, 2) + 10) << threads;
    // a failed batch is recorded too: the task that threw counts what it did before
    EXPECT_THROW(pool.ParallelFor(2,
                                  [&](int worker, int i) {
                                    counter[worker] += 7;
                                    if (i == 1) throw std::runtime_error("boom");
                                  }),
                 std::runtime_error);
    EXPECT_EQ(pool.load().work, work + 10 + 14) << threads;
    pool.ResetLoad();
    EXPECT_EQ(pool.load().work, 0);
    EXPECT_EQ(pool.load().span[2], 0);
  }
}

// the pool's time (PoolTime): every batch counted, the handed-off ones (more than one worker and
// one task) with their hand-off inside the batch's time; nothing handed off at 1 thread; reset
// with the load
TEST(ThreadPoolTest, TimeCountsBatchesAndTheirHandOff) {
  for (int threads : {1, 2, 3}) {
    ThreadPool pool(threads);
    std::atomic<int> count{0};
    pool.ParallelFor(0, [&](int, int) { ++count; });  // no batch
    pool.ParallelFor(1, [&](int, int) { ++count; });
    for (int k = 0; k < 5; ++k) pool.ParallelFor(8, [&](int, int) { ++count; });
    EXPECT_EQ(count.load(), 41);
    const PoolTime& t = pool.time();
    EXPECT_EQ(t.batches, 6) << threads;
    EXPECT_EQ(t.handed_off, threads > 1 ? 5 : 0) << threads;
    EXPECT_GT(t.seconds, 0.0) << threads;
    EXPECT_GT(t.cpu_seconds, 0.0) << threads;
    EXPECT_GE(t.wake_seconds, 0.0) << threads;
    EXPECT_GE(t.wait_seconds, 0.0) << threads;
    EXPECT_LE(t.wake_seconds, t.seconds) << threads;
    EXPECT_LE(t.wait_seconds, t.seconds) << threads;
    if (threads == 1) {
      EXPECT_EQ(t.wake_seconds, 0.0);
      EXPECT_EQ(t.wait_seconds, 0.0);
    }
    PoolTime sum;
    sum += t;
    sum += t;
    EXPECT_EQ(sum.batches, 12);
    EXPECT_EQ(sum.seconds, 2 * t.seconds);
    pool.ResetLoad();
    EXPECT_EQ(pool.time().batches, 0);
    EXPECT_EQ(pool.time().seconds, 0.0);
  }
}

// no busy-waiting when idle: the workers poll for the next batch for at most kSpinSeconds (200
// us), so after an idle pause 1000 times as long each of them sleeps when the next batch comes
TEST(ThreadPoolTest, IdleWorkersSleep) {
  ThreadPool pool(3);
  std::atomic<int> count{0};
  pool.ParallelFor(4, [&](int, int) { ++count; });
  const long long sleeps = pool.time().sleeps;
  std::this_thread::sleep_for(std::chrono::duration<double>(1000 * ThreadPool::kSpinSeconds));
  pool.ParallelFor(4, [&](int, int) { ++count; });
  EXPECT_EQ(pool.time().sleeps - sleeps, 2);
  EXPECT_EQ(count.load(), 8);
}

}  // namespace
}  // namespace mjsysid

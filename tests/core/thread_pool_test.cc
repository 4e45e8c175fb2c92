#include "core/thread_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <vector>

namespace mjsysid {
namespace {

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

}  // namespace
}  // namespace mjsysid

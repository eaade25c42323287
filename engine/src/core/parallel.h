// A minimal parallel loop on std::thread with dynamic scheduling.
#pragma once
#include <algorithm>
#include <atomic>
#include <thread>
#include <vector>

namespace photic {

// The threads parallel_for runs n items on: `threads` (0: all cores), at most n, at least 1.
inline int thread_count(int threads, size_t n) {
    if (threads <= 0) threads = int(std::max(1u, std::thread::hardware_concurrency()));
    return int(std::min<size_t>(size_t(threads), std::max<size_t>(n, 1)));
}

// Runs body(i, thread_index) for i in [0, n) on thread_count(threads, n) threads.
template <class F>
void parallel_for(size_t n, int threads, F&& body) {
    threads = thread_count(threads, n);
    std::atomic<size_t> next{0};
    auto worker = [&](int tid) {
        for (;;) {
            size_t i = next.fetch_add(1);
            if (i >= n) break;
            body(i, tid);
        }
    };
    if (threads == 1) { worker(0); return; }
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t) pool.emplace_back(worker, t);
    for (auto& th : pool) th.join();
}

}  // namespace photic

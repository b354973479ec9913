// The servo tick must not allocate: count every global operator new.
// Replacing the global operator new/delete pair with malloc/free is correct;
// GCC cannot see that the pair matches once std::allocator is inlined.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif
#include <atomic>
#include <cstdlib>
#include <new>
#include <random>

#include <gtest/gtest.h>

#include "common/haptics/proxy/virtual_proxy.h"
#include "common/mapping/local_map.h"
#include "tests/common/haptics/proxy/proxy_test_util.h"

namespace {
std::atomic<long> g_allocations{0};
}

void* operator new(std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

namespace hemm::haptics {
namespace {

TEST(TickAllocation, ProxyTickAndMapQueryAllocateNothing) {
  // A cluttered map: a room, a thin wall, a corner, scattered posts.
  ExactScene scene;
  add_box(scene, {-3, -3}, {3, 3});
  add_thick_wall(scene, {0.5, -2}, {0.5, 1}, 0.01);
  scene.segments.push_back({{-2, 1}, {-1, 2}});
  for (int i = 0; i < 40; ++i) scene.segments.push_back({{-2.5 + 0.1 * i, -1.0}, {-2.45 + 0.1 * i, -1.05}});
  const mapping::MapSnapshot map = test::snapshot_of(scene, {0, 0}, 0.1);
  ProxyModel m;
  ProxyData d = make_proxy_data(m);  // all buffers here, before counting
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-3.5, 3.5);
  std::vector<Eigen::Vector3d> path(5000);
  for (auto& p : path) p = Eigen::Vector3d(u(rng), u(rng), 0.0);  // large jumps: sweeps, slides, corners
  std::vector<std::uint32_t> out(256);

  const long before = g_allocations.load();
  std::size_t hits = 0;
  for (const auto& p : path) {
    proxy_tick(m, map, d, p, 20.0);
    hits += mapping::query_segments(map, p.head<2>(), 0.3, out.data(), out.size());
  }
  const long during = g_allocations.load() - before;
  EXPECT_EQ(during, 0) << "allocations in " << path.size() << " ticks";
  EXPECT_GT(hits, 0u);
  EXPECT_GT(d.ticks, 0u);
  // Control: the counter does see allocations.
  auto* probe = new std::vector<int>(10);
  EXPECT_GT(g_allocations.load() - before, during);
  delete probe;
}

}  // namespace
}  // namespace hemm::haptics

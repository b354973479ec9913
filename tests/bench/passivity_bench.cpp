// Time per tick of the 6-DoF TDPA, both ends, both arms (issue 25, part 5):
// each tick takes the peer's energy message (receive_peer), then runs the
// operator end's observer and controller (operator_arm_tick) and the robot
// end's (robot_arm_tick) for two arms. Signals are precomputed random
// wrenches and twists with a thin energy budget, so the controllers act on
// most ticks (the share is printed): the branch that costs the most.
//
// A tick costs tens of ns, near the steady clock's own cost, so the clock
// reads a block of 64 ticks: per-tick median and p99 are over blocks
// (ns / 64), wall time of the steady clock; the thread's CPU time over the
// whole run is printed beside it (meaningful on a loaded machine).
//
// Usage: passivity_bench [ticks]   (default 2 000 000)
#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include "common/clock/steady_clock.h"
#include "common/haptics/passivity/tdpa_arm.h"

namespace {

namespace td = hemm::haptics::tdpa;

struct BenchSample {
  td::ArmWrench robot_wrench, hand_wrench;
  td::ArmTwist hand_twist, received_twist;
  td::Vec6 op_in, robot_in;  // the energies carried by the peers' messages
};

double bench_quantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))];
}

}  // namespace

int main(int argc, char** argv) {
  const long ticks_arg = argc > 1 ? std::strtol(argv[1], nullptr, 10) : 2'000'000;
  if (ticks_arg < 6400) {
    std::fprintf(stderr, "passivity_bench: ticks must be a number >= 6400\n");
    return 2;
  }
  constexpr int kBlock = 64;
  const auto blocks = static_cast<std::size_t>(ticks_arg / kBlock);
  const double dt = 1e-3;
  // 4096 distinct samples, cycled.
  std::mt19937 rng(42);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<BenchSample> s(4096);
  td::Vec6 e_op = td::Vec6::Zero(), e_rob = td::Vec6::Zero();
  for (BenchSample& x : s) {
    x.robot_wrench = {Eigen::Vector3d(g(rng), g(rng), g(rng)) * 10, Eigen::Vector3d(g(rng), g(rng), g(rng))};
    x.hand_wrench = x.robot_wrench;
    x.hand_twist = {Eigen::Vector3d(g(rng), g(rng), g(rng)) * 0.1, Eigen::Vector3d(g(rng), g(rng), g(rng)) * 0.3};
    x.received_twist = x.hand_twist;
    e_op += td::Vec6::Constant(2e-4);
    e_rob += td::Vec6::Constant(2e-4);
    x.op_in = e_op;
    x.robot_in = e_rob;
  }
  std::array<td::ArmSide, 2> op{}, rob{};
  std::vector<double> per_tick_ns;
  per_tick_ns.reserve(blocks);
  double checksum = 0;
  std::uint64_t seq = 0;
  const double cpu0 = hemm::thread_cpu_s();
  const std::int64_t wall0 = hemm::steady_now_ns();
  for (std::size_t b = 0; b < blocks; ++b) {
    const std::int64_t t0 = hemm::steady_now_ns();
    for (int k = 0; k < kBlock; ++k) {
      const BenchSample& x = s[seq % s.size()];
      ++seq;
      for (int arm = 0; arm < 2; ++arm) {
        td::receive_peer<6>(op[static_cast<std::size_t>(arm)], seq, x.robot_in);
        td::receive_peer<6>(rob[static_cast<std::size_t>(arm)], seq, x.op_in);
        const td::ArmWrench w = td::operator_arm_tick(op[static_cast<std::size_t>(arm)], x.hand_wrench, x.hand_twist, dt);
        const td::ArmTwist v = td::robot_arm_tick(rob[static_cast<std::size_t>(arm)], x.received_twist, x.robot_wrench, dt);
        checksum += w.force.x() + v.omega.z();
      }
    }
    per_tick_ns.push_back(static_cast<double>(hemm::steady_now_ns() - t0) / kBlock);
  }
  const double wall_s = 1e-9 * static_cast<double>(hemm::steady_now_ns() - wall0);
  const double cpu_s = hemm::thread_cpu_s() - cpu0;
  const double n = static_cast<double>(blocks) * kBlock;
  std::printf("passivity_bench: 6-DoF TDPA, both ends, two arms per tick; %zu ticks\n",
              static_cast<std::size_t>(n));
  std::printf("  ns per tick (wall, blocks of %d): median %.1f  p99 %.1f  max %.1f\n", kBlock,
              bench_quantile(per_tick_ns, 0.5), bench_quantile(per_tick_ns, 0.99),
              *std::max_element(per_tick_ns.begin(), per_tick_ns.end()));
  std::printf("  ns per tick (mean): wall %.1f  thread CPU %.1f\n", 1e9 * wall_s / n, 1e9 * cpu_s / n);
  std::printf("  PC active: operator %.1f %%, robot %.1f %% of ticks (arm 0); checksum %.3g\n",
              100.0 * static_cast<double>(op[0].pc_active_ticks) / n,
              100.0 * static_cast<double>(rob[0].pc_active_ticks) / n, checksum);
  return 0;
}

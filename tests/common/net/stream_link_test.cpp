// StreamLink over real loopback sockets: a flood of rejected datagrams costs
// counters only, no allocation (no address text built per datagram).
#include "common/net/stream_link.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <thread>

#include "common/net/datagram.h"
#include "tests/operator/servo/alloc_counter.h"

namespace hemm::net {
namespace {

bool wait_received(StreamLink& link, uint64_t n) {
  for (int i = 0; i < 500; ++i) {
    if (link.statistics().rx.received >= n) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

TEST(StreamLink, RejectedDatagramsCostNoAllocation) {
  asio::io_context io;
  StreamLinkParams p;
  p.role = "robot";
  p.learn_peer_from_source = true;
  StreamLink link(io, p);
  std::string err;
  // Dual stack: IPv4 senders show up as ::ffff:127.0.0.1, text too long for a
  // short-string buffer, so building it per datagram would allocate.
  if (!link.bind(asio::ip::udp::endpoint(asio::ip::address_v6::any(), 0), &err)) GTEST_SKIP() << err;
  Key k{};
  for (size_t i = 0; i < k.size(); ++i) k[i] = static_cast<uint8_t>(i * 29 + 7);
  link.open_session(42, k, k, std::nullopt);
  const uint16_t port = link.local_endpoint().port();
  std::thread net([&] { io.run(); });

  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  to.sin_port = htons(port);
  // Rejected for every reason the receiver checks before and at the AEAD.
  std::vector<std::vector<uint8_t>> bad;
  bad.push_back(std::vector<uint8_t>(20, 0x48));         // too short
  bad.push_back(std::vector<uint8_t>(100, 0x00));        // bad magic
  std::vector<uint8_t> d;
  encode_datagram(k, DatagramHeader{43, 1, 0}, std::vector<uint8_t>(30, 1), &d);  // unknown session
  bad.push_back(d);
  Key wrong = k;
  wrong[0] ^= 1;
  encode_datagram(wrong, DatagramHeader{42, 1, 0}, std::vector<uint8_t>(30, 1), &d);  // bad tag
  bad.push_back(d);
  auto send_all = [&](int n) {
    for (int i = 0; i < n; ++i) {
      const auto& b = bad[static_cast<size_t>(i) % bad.size()];
      ::sendto(fd, b.data(), b.size(), 0, reinterpret_cast<sockaddr*>(&to), sizeof to);
      if (i % 64 == 63) std::this_thread::sleep_for(std::chrono::milliseconds(1));  // no socket-buffer drops
    }
  };
  send_all(200);  // warm-up: handler memory, first-time paths
  ASSERT_TRUE(wait_received(link, 200));
  asio::post(io, [] { hemm::test::count_allocations_on_this_thread(true); });
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const uint64_t before = hemm::test::counted_allocations();
  send_all(4000);
  ASSERT_TRUE(wait_received(link, 4200));
  asio::post(io, [] { hemm::test::count_allocations_on_this_thread(false); });
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const uint64_t allocations = hemm::test::counted_allocations() - before;
  const auto st = link.statistics();
  std::printf("4000 rejected datagrams: %llu allocations on the network thread (its timers included)\n",
              static_cast<unsigned long long>(allocations));
  EXPECT_EQ(st.rx.delivered, 0u);
  EXPECT_EQ(st.rx.rejected_total(), st.rx.received);
  // The link's own 50 ms heartbeat/ping timer allocates a few messages while
  // the window is open; per datagram there must be nothing.
  EXPECT_LT(allocations, 200u);
  ::close(fd);
  asio::post(io, [&] { link.stop(); });
  io.stop();
  net.join();
}

}  // namespace
}  // namespace hemm::net

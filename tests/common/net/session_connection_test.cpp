// SessionConnection over a real loopback TCP connection: the write queue is
// bounded and a peer that stops reading gets its connection closed.
#include "common/net/session_connection.h"

#include <gtest/gtest.h>

namespace hemm::net {
namespace {

TEST(SessionConnection, WriteQueueIsBoundedAndAPeerThatStopsReadingIsClosed) {
  asio::io_context io;
  asio::ip::tcp::acceptor acceptor(io, asio::ip::tcp::endpoint(asio::ip::address_v4::loopback(), 0));
  asio::ip::tcp::socket peer(io, asio::ip::tcp::v4());  // never reads
  peer.set_option(asio::socket_base::receive_buffer_size(4096));
  peer.connect(acceptor.local_endpoint());
  asio::ip::tcp::socket ours = acceptor.accept();
  ours.set_option(asio::socket_base::send_buffer_size(4096));
  auto conn = std::make_shared<SessionConnection>(std::move(ours), 64 * 1024);
  bool closed = false;
  std::string reason;
  conn->start([](std::span<const uint8_t>) {}, [](const wire::SessionFrame&) {},
              [&](const std::string& r) {
                closed = true;
                reason = r;
              });
  size_t frames = 0, most_queued = 0;
  for (; frames < 200 && !closed; ++frames) {
    conn->send_raw(std::vector<uint8_t>(64 * 1024, 0x5a));
    most_queued = std::max(most_queued, conn->queued_bytes());
    io.poll();  // the socket takes what its buffers hold, then stalls
  }
  std::printf("closed after %zu frames of 64 KiB; at most %zu bytes queued (limit %zu)\n", frames, most_queued,
              conn->max_queued_bytes());
  EXPECT_TRUE(closed) << "200 frames (12.5 MiB) queued for a peer that does not read";
  EXPECT_NE(reason.find("write queue full"), std::string::npos) << reason;
  EXPECT_LE(most_queued, conn->max_queued_bytes());
  EXPECT_EQ(conn->max_queued_bytes(), size_t{4} * (64 * 1024 + kTagBytes + kFrameHeaderBytes) > (size_t{1} << 20)
                                          ? size_t{4} * (64 * 1024 + kTagBytes + kFrameHeaderBytes)
                                          : size_t{1} << 20);
  EXPECT_FALSE(conn->is_open());
}

}  // namespace
}  // namespace hemm::net

#include "tests/integration/link/link_tap.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <deque>

#include "common/clock/steady_clock.h"

namespace hemm::test {
namespace {


sockaddr_in loopback(int port) {
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(static_cast<uint16_t>(port));
  return a;
}

int bound_socket(int type, int* port) {
  const int fd = ::socket(AF_INET, type, 0);
  sockaddr_in a = loopback(0);
  ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t len = sizeof a;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
  if (port) *port = ntohs(a.sin_port);
  return fd;
}

bool write_all(int fd, const uint8_t* p, size_t n) {
  while (n > 0) {
    const ssize_t w = ::send(fd, p, n, MSG_NOSIGNAL);
    if (w <= 0) return false;
    p += w;
    n -= static_cast<size_t>(w);
  }
  return true;
}

}  // namespace

LinkTap::LinkTap(Options o) : o_(o) {
  tcp_listen_ = bound_socket(SOCK_STREAM, &tcp_port_);
  ::listen(tcp_listen_, 4);
  udp_front_ = bound_socket(SOCK_DGRAM, &udp_port_);
  udp_back_ = bound_socket(SOCK_DGRAM, nullptr);
  udp_attacker_ = bound_socket(SOCK_DGRAM, nullptr);
  thread_ = std::thread([this] { run(); });
}

LinkTap::~LinkTap() {
  stop_.store(true);
  thread_.join();
  for (int fd : {tcp_listen_, tcp_client_, tcp_server_, udp_front_, udp_back_, udp_attacker_}) {
    if (fd >= 0) ::close(fd);
  }
}

std::vector<LinkTap::Datagram> LinkTap::datagrams() const {
  std::lock_guard<std::mutex> lk(mu_);
  return datagrams_;
}

std::vector<uint8_t> LinkTap::tcp_bytes(bool c2s) const {
  std::lock_guard<std::mutex> lk(mu_);
  return c2s ? tcp_c2s_ : tcp_s2c_;
}

void LinkTap::run() {
  struct Held {
    int64_t release_ns;
    std::vector<uint8_t> bytes;
  };
  std::deque<Held> held;  // client -> server, in order (fixed delay keeps order)
  sockaddr_in client{};
  bool have_client = false;
  const sockaddr_in server_udp = loopback(o_.server_udp_port);
  std::vector<uint8_t> buf(65536);
  while (!stop_.load()) {
    const int64_t now = hemm::steady_now_ns();
    while (!held.empty() && held.front().release_ns <= now) {
      ::sendto(udp_back_, held.front().bytes.data(), held.front().bytes.size(), 0,
               reinterpret_cast<const sockaddr*>(&server_udp), sizeof server_udp);
      held.pop_front();
    }
    int timeout_ms = 20;
    if (!held.empty()) timeout_ms = static_cast<int>(std::max<int64_t>(0, (held.front().release_ns - now) / 1'000'000));
    std::vector<pollfd> fds = {{tcp_listen_, POLLIN, 0},
                               {udp_front_, POLLIN, 0},
                               {udp_back_, POLLIN, 0},
                               {udp_attacker_, POLLIN, 0},
                               {tcp_client_, POLLIN, 0},
                               {tcp_server_, POLLIN, 0}};
    if (::poll(fds.data(), fds.size(), std::min(timeout_ms, 20)) <= 0) continue;
    if (fds[0].revents & POLLIN) {
      const int c = ::accept(tcp_listen_, nullptr, nullptr);
      if (c >= 0 && tcp_client_ < 0) {
        tcp_client_ = c;
        tcp_server_ = ::socket(AF_INET, SOCK_STREAM, 0);
        sockaddr_in s = loopback(o_.server_tcp_port);
        ::connect(tcp_server_, reinterpret_cast<sockaddr*>(&s), sizeof s);
      } else if (c >= 0) {
        ::close(c);  // one session connection is all these tests need
      }
    }
    if (fds[1].revents & POLLIN) {
      sockaddr_in from{};
      socklen_t len = sizeof from;
      const ssize_t n = ::recvfrom(udp_front_, buf.data(), buf.size(), 0, reinterpret_cast<sockaddr*>(&from), &len);
      if (n > 0) {
        client = from;
        have_client = true;
        std::vector<uint8_t> d(buf.begin(), buf.begin() + n);
        if (attack_.load()) {
          ::sendto(udp_attacker_, d.data(), d.size(), 0, reinterpret_cast<const sockaddr*>(&server_udp),
                   sizeof server_udp);
          ++attacker_sent_;
        }
        {
          std::lock_guard<std::mutex> lk(mu_);
          datagrams_.push_back({true, hemm::steady_now_ns(), d});
        }
        held.push_back({hemm::steady_now_ns() + int64_t{o_.c2s_delay_ms} * 1'000'000, std::move(d)});
      }
    }
    if (fds[2].revents & POLLIN) {
      const ssize_t n = ::recv(udp_back_, buf.data(), buf.size(), 0);
      if (n > 0 && have_client) {
        ::sendto(udp_front_, buf.data(), static_cast<size_t>(n), 0, reinterpret_cast<const sockaddr*>(&client),
                 sizeof client);
        ++s2c_forwarded_;
        std::lock_guard<std::mutex> lk(mu_);
        datagrams_.push_back({false, hemm::steady_now_ns(), std::vector<uint8_t>(buf.begin(), buf.begin() + n)});
      }
    }
    if (fds[3].revents & POLLIN) {
      if (::recv(udp_attacker_, buf.data(), buf.size(), 0) >= 0) ++attacker_received_;
    }
    for (int k : {4, 5}) {
      if (fds[static_cast<size_t>(k)].fd < 0 || !(fds[static_cast<size_t>(k)].revents & (POLLIN | POLLHUP))) continue;
      const bool c2s = k == 4;
      const int from = c2s ? tcp_client_ : tcp_server_;
      const int to = c2s ? tcp_server_ : tcp_client_;
      const ssize_t n = ::recv(from, buf.data(), buf.size(), 0);
      if (n <= 0) {
        ::shutdown(to, SHUT_WR);
        ::close(from);
        (c2s ? tcp_client_ : tcp_server_) = -1;
        continue;
      }
      {
        std::lock_guard<std::mutex> lk(mu_);
        auto& rec = c2s ? tcp_c2s_ : tcp_s2c_;
        rec.insert(rec.end(), buf.begin(), buf.begin() + n);
      }
      write_all(to, buf.data(), static_cast<size_t>(n));
    }
  }
}

}  // namespace hemm::test

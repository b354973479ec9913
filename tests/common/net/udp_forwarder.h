// Test helper: a small UDP forwarder on loopback, standing where a NAT or an
// on-path box stands between the operator and the robot. The operator sends
// to front_port(); each datagram goes on to the robot from the forwarder's
// current exit socket, and whatever the robot sends to an exit socket goes
// back to the operator (to the address it last sent from). The test can
//   * pause it (both directions dropped: a link outage),
//   * rebind its exit (a NAT that gives the flow a new port),
//   * act as the on-path attacker: send a copy of the operator's newest
//     datagram to the robot from a second exit socket of its own, keep
//     whatever the robot sends to that second socket, and pass it on to the
//     operator later (as if it came from the robot), holding it as long as
//     it likes.
// Plain POSIX sockets and one thread; nothing of hemm inside.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <deque>
#include <mutex>
#include <thread>
#include <vector>

namespace hemm::test {

// A UDP socket bound to 127.0.0.1 on a free port (written to *port).
inline int open_loopback_udp(uint16_t* port) {
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t len = sizeof a;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
  *port = ntohs(a.sin_port);
  return fd;
}

class UdpForwarder {
 public:
  explicit UdpForwarder(uint16_t robot_port) {
    robot_.sin_family = AF_INET;
    robot_.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    robot_.sin_port = htons(robot_port);
    front_ = open_loopback_udp(&front_port_);
    uint16_t exit_port = 0;
    exit_ = open_loopback_udp(&exit_port);
    exit_port_ = exit_port;
    side_ = open_loopback_udp(&side_port_);
    thread_ = std::thread([this] { run(); });
  }
  ~UdpForwarder() {
    stop_ = true;
    thread_.join();
    for (int fd : {front_, exit_, side_}) ::close(fd);
    for (int fd : retired_) ::close(fd);
  }
  UdpForwarder(const UdpForwarder&) = delete;
  UdpForwarder& operator=(const UdpForwarder&) = delete;

  uint16_t front_port() const { return front_port_; }
  uint16_t exit_port() const { return exit_port_.load(); }  // the genuine path's source port at the robot
  uint16_t side_port() const { return side_port_; }         // the attacker's second exit

  void set_paused(bool paused) { paused_ = paused; }
  // Operator -> robot only (a gap in the genuine path's traffic; the robot's
  // datagrams still reach the operator).
  // What the operator sent meanwhile is kept (the last 256 datagrams) until
  // the pause ends.
  void set_upstream_paused(bool paused) {
    std::lock_guard<std::mutex> lk(mu_);
    up_paused_ = paused;
    if (!paused) held_up_.clear();
  }
  // Sends what the operator sent during the upstream pause, in order, to the
  // robot from the side socket (the attacker relaying the operator's traffic
  // from its own address), and forgets it.
  size_t send_held_upstream_from_side() {
    std::lock_guard<std::mutex> lk(mu_);
    size_t n = 0;
    for (const auto& d : held_up_) {
      n += ::sendto(side_, d.data(), d.size(), 0, reinterpret_cast<const sockaddr*>(&robot_), sizeof robot_) ==
           static_cast<ssize_t>(d.size());
    }
    held_up_.clear();
    return n;
  }
  // A NAT rebinding: later datagrams leave from a fresh socket (the old one
  // is kept open but no longer used).
  void rebind_exit() {
    std::lock_guard<std::mutex> lk(mu_);
    retired_.push_back(exit_);
    uint16_t port = 0;
    exit_ = open_loopback_udp(&port);
    exit_port_ = port;
  }
  // Sends a copy of the operator's newest datagram to the robot from the side socket.
  bool send_copy_from_side() {
    std::lock_guard<std::mutex> lk(mu_);
    if (last_up_.empty()) return false;
    return ::sendto(side_, last_up_.data(), last_up_.size(), 0, reinterpret_cast<const sockaddr*>(&robot_),
                    sizeof robot_) == static_cast<ssize_t>(last_up_.size());
  }
  // Datagrams the robot sent to the side socket, held (not passed on).
  size_t side_held() {
    std::lock_guard<std::mutex> lk(mu_);
    return side_held_.size();
  }
  size_t side_received() const { return side_received_.load(); }
  // Passes every held side datagram to the operator now (from the front
  // socket: the address the operator sends to, so it looks like the robot's).
  size_t release_side_to_operator() {
    std::lock_guard<std::mutex> lk(mu_);
    size_t n = 0;
    while (!side_held_.empty()) {
      const auto& d = side_held_.front();
      if (have_client_) ::sendto(front_, d.data(), d.size(), 0, reinterpret_cast<const sockaddr*>(&client_),
                                 sizeof client_);
      side_held_.pop_front();
      ++n;
    }
    return n;
  }
  uint64_t forwarded_up() const { return up_.load(); }
  uint64_t forwarded_down() const { return down_.load(); }

 private:
  void run() {
    std::vector<uint8_t> buf(65536);
    while (!stop_) {
      int exit_fd;
      std::vector<int> old;
      {
        std::lock_guard<std::mutex> lk(mu_);
        exit_fd = exit_;
        old = retired_;
      }
      std::vector<pollfd> fds = {{front_, POLLIN, 0}, {exit_fd, POLLIN, 0}, {side_, POLLIN, 0}};
      for (int fd : old) fds.push_back({fd, POLLIN, 0});
      if (::poll(fds.data(), fds.size(), 10) <= 0) continue;
      for (const pollfd& p : fds) {
        if (!(p.revents & POLLIN)) continue;
        sockaddr_in from{};
        socklen_t len = sizeof from;
        const ssize_t n = ::recvfrom(p.fd, buf.data(), buf.size(), 0, reinterpret_cast<sockaddr*>(&from), &len);
        if (n <= 0) continue;
        const std::vector<uint8_t> d(buf.begin(), buf.begin() + n);
        std::lock_guard<std::mutex> lk(mu_);
        if (p.fd == front_) {
          client_ = from;
          have_client_ = true;
          last_up_ = d;
          if (up_paused_) {
            held_up_.push_back(d);
            if (held_up_.size() > 256) held_up_.pop_front();
          }
          if (paused_ || up_paused_) continue;
          ::sendto(exit_, d.data(), d.size(), 0, reinterpret_cast<const sockaddr*>(&robot_), sizeof robot_);
          ++up_;
        } else if (p.fd == side_) {
          ++side_received_;
          side_held_.push_back(d);
        } else if (p.fd == exit_fd) {
          if (paused_ || !have_client_) continue;
          ::sendto(front_, d.data(), d.size(), 0, reinterpret_cast<const sockaddr*>(&client_), sizeof client_);
          ++down_;
        }
        // A retired exit: the NAT forgot that mapping; whatever comes there is lost.
      }
    }
  }

  sockaddr_in robot_{};
  sockaddr_in client_{};
  bool have_client_ = false;
  int front_ = -1, exit_ = -1, side_ = -1;
  uint16_t front_port_ = 0, side_port_ = 0;
  std::atomic<uint16_t> exit_port_{0};
  std::vector<int> retired_;
  std::vector<uint8_t> last_up_;
  std::deque<std::vector<uint8_t>> side_held_, held_up_;
  std::mutex mu_;
  std::atomic<bool> paused_{false}, up_paused_{false}, stop_{false};
  std::atomic<uint64_t> up_{0}, down_{0}, side_received_{0};
  std::thread thread_;
};

}  // namespace hemm::test

// A man in the middle for loopback tests (one thread, poll): forwards one
// TCP connection and the UDP stream between a client (the operator) and a
// server (the robot), records every TCP byte and every datagram per
// direction, can delay client->server datagrams, and can play an attacker
// that sends a copy of every client->server datagram to the server from its
// own port at once (so the copy arrives ahead of the delayed original) and
// counts whatever the server sends to that port.
#pragma once

#include <atomic>
#include <cstdint>
#include <mutex>
#include <thread>
#include <vector>

namespace hemm::test {

class LinkTap {
 public:
  struct Options {
    int server_tcp_port = 0;
    int server_udp_port = 0;
    int c2s_delay_ms = 0;  // client -> server datagrams wait this long (the attacker's copies do not)
  };
  struct Datagram {
    bool c2s = false;
    int64_t t_ns = 0;  // steady clock at capture
    std::vector<uint8_t> bytes;
  };

  explicit LinkTap(Options o);
  ~LinkTap();
  LinkTap(const LinkTap&) = delete;
  LinkTap& operator=(const LinkTap&) = delete;

  int tcp_port() const { return tcp_port_; }  // the client connects here
  int udp_port() const { return udp_port_; }  // the client sends datagrams here

  void set_attack(bool on) { attack_.store(on); }
  uint64_t attacker_sent() const { return attacker_sent_.load(); }
  uint64_t attacker_received() const { return attacker_received_.load(); }
  uint64_t s2c_forwarded() const { return s2c_forwarded_.load(); }

  std::vector<Datagram> datagrams() const;
  std::vector<uint8_t> tcp_bytes(bool c2s) const;

 private:
  void run();

  Options o_;
  int tcp_listen_ = -1, tcp_client_ = -1, tcp_server_ = -1;
  int udp_front_ = -1, udp_back_ = -1, udp_attacker_ = -1;
  int tcp_port_ = 0, udp_port_ = 0;
  std::atomic<bool> stop_{false}, attack_{false};
  std::atomic<uint64_t> attacker_sent_{0}, attacker_received_{0}, s2c_forwarded_{0};
  mutable std::mutex mu_;
  std::vector<Datagram> datagrams_;
  std::vector<uint8_t> tcp_c2s_, tcp_s2c_;
  std::thread thread_;
};

}  // namespace hemm::test

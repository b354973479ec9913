// Local control of a running station (hemm-robot, hemm-operator), used for
// the e-stop from outside the station's own loop:
//  * ControlServer: a Unix-domain stream socket the station listens on
//    (--control-socket PATH). Each connection carries one command line
//    ("estop", "release", "status"; at most kMaxControlLine bytes) and gets
//    one reply line ("ok ..." or "error ..."), then closes. The socket file is
//    made owner-only (0600) before it accepts anything, so only the user
//    running the station (or root) can use it. A stale socket left by a dead
//    station is replaced; a live one, or any other kind of file, is an error.
//  * control_request(): the client side, for `hemm-robot estop ...` and
//    `hemm-operator estop ...`.
// (The e-stop keys on the station's terminal: common/terminal/terminal_keys.h.)
// All run on the caller's io_context (the station's network thread).
#pragma once

#include <asio.hpp>
#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <string>

namespace hemm::net {

inline constexpr std::size_t kMaxControlLine = 256;

class ControlServer {
 public:
  // respond() may be called later (e.g. when the robot acknowledged), on the
  // io_context's thread, at most once; if it is never called the client
  // times out.
  using Respond = std::function<void(const std::string& reply)>;
  using Handler = std::function<void(const std::string& command, Respond respond)>;

  ControlServer(asio::io_context& io, std::string path, Handler handler);
  ~ControlServer();  // stop()
  ControlServer(const ControlServer&) = delete;
  ControlServer& operator=(const ControlServer&) = delete;

  // Binds and listens. False with *error if the path is taken (a live
  // station, or not a socket) or cannot be bound.
  bool start(std::string* error);
  // Closes the socket and removes its file (idempotent).
  void stop();
  const std::string& path() const { return path_; }
  std::uint64_t requests() const;
  std::uint64_t rejected() const;  // over-long, empty or non-printable lines

 private:
  struct Shared;  // what pending connections still use after stop()
  struct Conn;
  static void accept(const std::shared_ptr<Shared>& sh);

  asio::io_context& io_;
  std::string path_;
  std::shared_ptr<Shared> sh_;
  bool bound_ = false;
};

// Sends one command to a station's control socket and returns its reply
// line (without the newline), or nullopt with *error (cannot connect, no
// reply within timeout).
std::optional<std::string> control_request(const std::string& path, const std::string& command,
                                           std::chrono::milliseconds timeout, std::string* error);

}  // namespace hemm::net

// Single key presses from a terminal (a station's stdin when it is a TTY):
// the terminal is switched to non-canonical, no-echo input while it runs
// (Ctrl-C still signals) and restored afterwards. Runs on the caller's
// io_context (the station's network thread).
#pragma once

#include <asio.hpp>
#include <functional>
#include <memory>
#include <string>

namespace hemm::terminal {

class TerminalKeys {
 public:
  TerminalKeys(asio::io_context& io, int fd, std::function<void(char key)> on_key);
  ~TerminalKeys();  // stop()
  TerminalKeys(const TerminalKeys&) = delete;
  TerminalKeys& operator=(const TerminalKeys&) = delete;

  // False with *error if fd is not a terminal.
  bool start(std::string* error);
  // Stops reading and restores the terminal's settings (idempotent).
  void stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hemm::terminal

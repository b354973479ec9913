#include "common/terminal/terminal_keys.h"

#include <termios.h>
#include <unistd.h>

#include <array>
#include <cstddef>

namespace hemm::terminal {

struct TerminalKeys::Impl {
  asio::posix::stream_descriptor in;
  std::function<void(char)> on_key;
  int fd;
  termios saved{};
  bool active = false;
  std::array<char, 16> buf{};
  Impl(asio::io_context& io, int f, std::function<void(char)> k) : in(io), on_key(std::move(k)), fd(f) {}
  void read() {
    in.async_read_some(asio::buffer(buf), [this](const asio::error_code& ec, std::size_t n) {
      if (ec) return;  // EOF (the terminal went away) or stopped
      for (std::size_t i = 0; i < n; ++i) on_key(buf[i]);
      read();
    });
  }
};

TerminalKeys::TerminalKeys(asio::io_context& io, int fd, std::function<void(char)> on_key)
    : impl_(std::make_unique<Impl>(io, fd, std::move(on_key))) {}

TerminalKeys::~TerminalKeys() { stop(); }

bool TerminalKeys::start(std::string* error) {
  Impl& m = *impl_;
  if (m.active) return true;
  if (!::isatty(m.fd)) {
    *error = "not a terminal";
    return false;
  }
  // A background process touching its controlling terminal's settings would
  // be stopped (SIGTTOU). (-1: not our controlling terminal: no job control.)
  if (const pid_t fg = ::tcgetpgrp(m.fd); fg >= 0 && fg != ::getpgrp()) {
    *error = "not the terminal's foreground process";
    return false;
  }
  if (::tcgetattr(m.fd, &m.saved) != 0) {
    *error = "cannot read the terminal's settings";
    return false;
  }
  termios raw = m.saved;
  raw.c_lflag &= static_cast<tcflag_t>(~(ICANON | ECHO));  // keys one by one, unechoed; ISIG stays (Ctrl-C)
  raw.c_cc[VMIN] = 1;
  raw.c_cc[VTIME] = 0;
  const int dup = ::dup(m.fd);  // the descriptor closes its own copy, never the station's stdin
  if (dup < 0 || ::tcsetattr(m.fd, TCSANOW, &raw) != 0) {
    if (dup >= 0) ::close(dup);
    *error = "cannot set the terminal's mode";
    return false;
  }
  m.in.assign(dup);
  m.active = true;
  m.read();
  return true;
}

void TerminalKeys::stop() {
  Impl& m = *impl_;
  if (!m.active) return;
  asio::error_code ec;
  m.in.cancel(ec);
  m.in.close(ec);
  ::tcsetattr(m.fd, TCSANOW, &m.saved);
  m.active = false;
}

}  // namespace hemm::terminal

// Single keys from a terminal (a pseudo-terminal here): unechoed, one by
// one, the terminal's settings restored afterwards; not a terminal refused.
#include "common/terminal/terminal_keys.h"

#include <fcntl.h>
#include <termios.h>
#include <unistd.h>

#include <cstdlib>
#include <string>

#include <gtest/gtest.h>

namespace ht = hemm::terminal;
using namespace std::chrono_literals;

TEST(TerminalKeys, KeysArriveOneByOneUnechoedAndTheTerminalIsRestored) {
  const int master = ::posix_openpt(O_RDWR | O_NOCTTY);
  ASSERT_GE(master, 0);
  ASSERT_EQ(::grantpt(master), 0);
  ASSERT_EQ(::unlockpt(master), 0);
  const int slave = ::open(::ptsname(master), O_RDWR | O_NOCTTY);
  ASSERT_GE(slave, 0);
  termios before{};
  ASSERT_EQ(::tcgetattr(slave, &before), 0);
  ASSERT_NE(before.c_lflag & ICANON, 0u);  // a fresh terminal is line-buffered

  asio::io_context io;
  std::string keys;
  {
    ht::TerminalKeys t(io, slave, [&](char k) { keys.push_back(k); });
    std::string err;
    ASSERT_TRUE(t.start(&err)) << err;
    termios during{};
    ASSERT_EQ(::tcgetattr(slave, &during), 0);
    EXPECT_EQ(during.c_lflag & (ICANON | ECHO), 0u);
    EXPECT_NE(during.c_lflag & ISIG, 0u);  // Ctrl-C still interrupts
    // Keys without Enter arrive at once.
    ASSERT_EQ(::write(master, "e R", 3), 3);
    for (int i = 0; i < 100 && keys.size() < 3; ++i) io.run_for(10ms);
    EXPECT_EQ(keys, "e R");
  }
  termios after{};
  ASSERT_EQ(::tcgetattr(slave, &after), 0);
  EXPECT_EQ(after.c_lflag, before.c_lflag);
  // Not a terminal: refused.
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  ht::TerminalKeys p(io, fds[0], [](char) {});
  std::string err;
  EXPECT_FALSE(p.start(&err));
  ::close(fds[0]);
  ::close(fds[1]);
  ::close(slave);
  ::close(master);
}

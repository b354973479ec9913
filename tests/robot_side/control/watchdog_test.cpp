// The command watchdog (robot_side/control/watchdog.h).
#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "robot_side/control/watchdog.h"

namespace hr = hemm::robot;

TEST(Watchdog, ExpiresAfterTheTimeout) {
  hr::Watchdog w;
  w.timeout_ns = 250'000'000;
  EXPECT_TRUE(hr::watchdog_expired(w, 0));  // nothing received yet
  hr::watchdog_feed(w, 1'000'000'000);
  EXPECT_FALSE(hr::watchdog_expired(w, 1'250'000'000));
  EXPECT_TRUE(hr::watchdog_expired(w, 1'250'000'001));
}

TEST(Watchdog, CountsFromTheCommandsSendTimeAndNeverFromTheFuture) {
  hr::Watchdog w;
  w.timeout_ns = 250'000'000;
  // Arrived at t = 1 s but sent (as the fastest command would have been) 150 ms earlier: 100 ms left.
  hr::watchdog_feed(w, 850'000'000, 1'000'000'000);
  EXPECT_FALSE(hr::watchdog_expired(w, 1'100'000'000));
  EXPECT_TRUE(hr::watchdog_expired(w, 1'100'000'001));
  // Held longer than the timeout: expired on arrival.
  hr::watchdog_feed(w, 600'000'000, 1'000'000'000);
  EXPECT_TRUE(hr::watchdog_expired(w, 1'000'000'000));
  // A send time after now (a clock estimate off) counts as now, not later.
  hr::watchdog_feed(w, 5'000'000'000, 2'000'000'000);
  EXPECT_TRUE(hr::watchdog_expired(w, 2'250'000'001));
}

// A session id's log form: 16 lower-case hex digits, leading zeros kept.
#include "common/net/session_id.h"

#include <gtest/gtest.h>

TEST(SessionId, SixteenLowerCaseHexDigitsWithLeadingZeros) {
  EXPECT_EQ(hemm::net::hex_id(0), "0000000000000000");
  EXPECT_EQ(hemm::net::hex_id(0xABCu), "0000000000000abc");
  EXPECT_EQ(hemm::net::hex_id(0x0123456789ABCDEFull), "0123456789abcdef");
  EXPECT_EQ(hemm::net::hex_id(~0ull), "ffffffffffffffff");
}

// Path validation: a copy of a genuine datagram from another address moves
// nothing; the address a challenge was sent to is validated by its token;
// rate limits hold under a flood of candidates.
#include "common/net/path_validation.h"

#include <gtest/gtest.h>

namespace hemm::net {
namespace {

constexpr int64_t kMsNs = 1'000'000;  // one millisecond in ns

PathAddress addr(uint8_t last, uint16_t port) {
  PathAddress a;
  a.ip[10] = 0xff;
  a.ip[11] = 0xff;
  a.ip[12] = 127;
  a.ip[15] = last;
  a.port = port;
  return a;
}

TEST(PathValidation, FirstAddressIsUsedOnlyAfterItsChallengeIsAnswered) {
  PathValidator v;
  const PathAddress op = addr(1, 5000);
  const auto tok = v.on_datagram(op, 0);
  ASSERT_TRUE(tok);
  EXPECT_FALSE(v.peer());
  // A wrong token, or one of the right length but never sent, validates nothing.
  PathToken wrong = *tok;
  wrong[0] ^= 1;
  EXPECT_FALSE(v.on_response(wrong, 10 * kMsNs));
  EXPECT_FALSE(v.on_response(std::span(tok->data(), 8), 10 * kMsNs));
  EXPECT_EQ(v.counters().responses_unmatched, 2u);
  ASSERT_EQ(v.on_response(*tok, 20 * kMsNs), op);
  EXPECT_EQ(v.peer(), op);
  EXPECT_EQ(v.counters().validated, 1u);
}

TEST(PathValidation, CopiesFromAnotherAddressGetNothingWhileThePeerIsAlive) {
  PathValidator v;
  const PathAddress op = addr(1, 5000), attacker = addr(2, 6000);
  ASSERT_TRUE(v.on_response(*v.on_datagram(op, 0), 1 * kMsNs));
  // The attacker's copies arrive first (new highest), the originals 75 ms
  // later as duplicates: every copy is ignored, no challenge goes out.
  for (int64_t t = 10 * kMsNs; t < 10'000 * kMsNs; t += 5 * kMsNs) {
    EXPECT_FALSE(v.on_datagram(attacker, t));
    EXPECT_FALSE(v.on_datagram(op, t + 75 * kMsNs));
  }
  EXPECT_EQ(v.peer(), op);
  EXPECT_EQ(v.counters().challenges_sent, 1u);
  EXPECT_GT(v.counters().ignored, 1000u);
}

TEST(PathValidation, AResponseRelayedFromTheAttackersAddressValidatesOnlyTheChallengedAddress) {
  // The token binds the address the challenge was sent to, not where the
  // response comes from: a copy of the operator's response sent by the
  // attacker validates the operator's address.
  PathValidator v;
  const PathAddress op = addr(1, 5000);
  const auto tok = v.on_datagram(op, 0);
  EXPECT_EQ(v.on_response(*tok, 3 * kMsNs), op);
}

TEST(PathValidation, AttackerRacingFromTheFirstDatagramCannotWinTheInitialPath) {
  PathValidator v;
  v.params().min_interval_ns = 0;
  const PathAddress op = addr(1, 5000), attacker = addr(2, 6000);
  // The copy arrives first and is challenged; the original (a duplicate) is
  // challenged too. Only the operator can answer.
  const auto to_attacker = v.on_datagram(attacker, 0);
  const auto to_op = v.on_datagram(op, 75 * kMsNs);
  ASSERT_TRUE(to_attacker);
  ASSERT_TRUE(to_op);
  EXPECT_EQ(v.on_response(*to_op, 150 * kMsNs), op);
  // The attacker cannot read its token; even if it guessed, the path is held.
  EXPECT_FALSE(v.on_datagram(attacker, 160 * kMsNs));
  EXPECT_EQ(v.peer(), op);
}

TEST(PathValidation, AnOperatorThatMovedIsValidatedAfterItsOldPathWentQuiet) {
  PathValidator v;
  v.params().quiet_ns = 250 * kMsNs;
  const PathAddress old_path = addr(1, 5000), new_path = addr(1, 5001);
  ASSERT_TRUE(v.on_response(*v.on_datagram(old_path, 0), 1 * kMsNs));
  EXPECT_FALSE(v.on_datagram(old_path, 100 * kMsNs));
  EXPECT_FALSE(v.on_datagram(new_path, 200 * kMsNs));  // old path heard 100 ms ago
  const auto tok = v.on_datagram(new_path, 360 * kMsNs);
  ASSERT_TRUE(tok);
  EXPECT_EQ(v.peer(), old_path);  // still the old one until answered
  EXPECT_EQ(v.on_response(*tok, 400 * kMsNs), new_path);
  EXPECT_EQ(v.counters().validated, 2u);
}

// Issue 23 item 4: a token earned while the path was quiet is worth nothing
// once the path carries traffic again: the response validates its address
// only if the current path is still silent when it arrives. The token is
// used up by the attempt.
TEST(PathValidation, AResponseArrivingWhileTheCurrentPathCarriesTrafficValidatesNothing) {
  PathValidator v;
  v.params().quiet_ns = 250 * kMsNs;
  const PathAddress op = addr(1, 5000), forwarder = addr(2, 6000);
  ASSERT_TRUE(v.on_response(*v.on_datagram(op, 0), 1 * kMsNs));
  // A 300 ms gap in the operator's traffic: a copy from elsewhere is challenged.
  const auto tok = v.on_datagram(forwarder, 300 * kMsNs);
  ASSERT_TRUE(tok);
  // The operator's traffic is back; the held token is redeemed 100 ms later.
  for (int64_t t = 310 * kMsNs; t <= 400 * kMsNs; t += 10 * kMsNs) EXPECT_FALSE(v.on_datagram(op, t));
  EXPECT_FALSE(v.on_response(*tok, 405 * kMsNs));
  EXPECT_EQ(v.peer(), op);
  // Used up: not even in a later quiet spell.
  EXPECT_FALSE(v.on_response(*tok, 700 * kMsNs));
  EXPECT_EQ(v.peer(), op);
  EXPECT_EQ(v.counters().validated, 1u);
}

// Tokens live 4 round trips within [250 ms, 8 s]: the link's measured round
// trip, else the one the session's validation took, else (nothing known, no
// path to take over yet) the ceiling.
TEST(PathValidation, TokensLiveFourRoundTripsWithinAFloorAndACeiling) {
  PathValidator v;
  EXPECT_EQ(v.token_lifetime_ns(), 8000 * kMsNs);
  const PathAddress op = addr(1, 5000), other = addr(3, 7000);
  const auto first = v.on_datagram(op, 0);
  ASSERT_TRUE(v.on_response(*first, 100 * kMsNs));  // the validation took 100 ms
  EXPECT_EQ(v.token_lifetime_ns(), 400 * kMsNs);
  // A token issued in a quiet spell, redeemed 450 ms later: expired.
  const auto tok = v.on_datagram(other, 400 * kMsNs);
  ASSERT_TRUE(tok);
  EXPECT_FALSE(v.on_response(*tok, 851 * kMsNs));
  EXPECT_EQ(v.counters().responses_unmatched, 1u);
  v.params().rtt_ns = 20 * kMsNs;  // measured by the link: the floor
  EXPECT_EQ(v.token_lifetime_ns(), 250 * kMsNs);
  v.params().rtt_ns = 1000 * kMsNs;
  EXPECT_EQ(v.token_lifetime_ns(), 4000 * kMsNs);
  v.params().rtt_ns = 3000 * kMsNs;  // the ceiling
  EXPECT_EQ(v.token_lifetime_ns(), 8000 * kMsNs);
  v.reset();  // a new session knows nothing of the old one's round trip
  v.params().rtt_ns = 0;
  EXPECT_EQ(v.token_lifetime_ns(), 8000 * kMsNs);
}

TEST(PathValidation, ChallengesAreRateLimitedPerCandidateAndInAll) {
  PathValidator v;
  v.params().first_retry_ns = 1000 * kMsNs;  // as when a round trip of 500 ms is known
  v.params().max_retry_ns = 4000 * kMsNs;
  v.params().min_interval_ns = 20 * kMsNs;
  v.params().max_candidates = 4;
  v.params().max_tokens = 8;
  const PathAddress a = addr(9, 1);
  // One candidate sending at 1 kHz for 10 s: challenged at 0, 1, 3, 7 s.
  int to_a = 0;
  for (int64_t t = 0; t < 10'000 * kMsNs; t += kMsNs) to_a += v.on_datagram(a, t).has_value();
  EXPECT_EQ(to_a, 4);
  // 1000 distinct candidates in 1 s: at most one challenge per 20 ms.
  PathValidator w;
  w.params().min_interval_ns = 20 * kMsNs;
  w.params().max_candidates = 4;
  w.params().max_tokens = 8;
  int sent = 0;
  for (int i = 0; i < 1000; ++i) sent += w.on_datagram(addr(10, static_cast<uint16_t>(i)), i * kMsNs).has_value();
  EXPECT_LE(sent, 51);
  EXPECT_GE(sent, 40);
  EXPECT_GT(w.counters().rate_limited, 900u);
}

TEST(PathValidation, ExpiredAndEvictedTokensValidateNothing) {
  PathValidator v;
  v.params().token_max_ns = 1000 * kMsNs;  // the lifetime while no round trip is known
  v.params().min_interval_ns = 0;
  v.params().max_tokens = 2;
  const auto t1 = v.on_datagram(addr(1, 1), 0);
  ASSERT_TRUE(t1);
  EXPECT_FALSE(v.on_response(*t1, 1001 * kMsNs));  // expired
  const auto t2 = v.on_datagram(addr(1, 2), 0);
  const auto t3 = v.on_datagram(addr(1, 3), 0);
  const auto t4 = v.on_datagram(addr(1, 4), 0);  // evicts t2 (t1 was evicted by t3)
  ASSERT_TRUE(t2 && t3 && t4);
  EXPECT_FALSE(v.on_response(*t2, 10 * kMsNs));
  EXPECT_EQ(v.on_response(*t4, 10 * kMsNs), addr(1, 4));
  EXPECT_EQ(v.counters().responses_unmatched, 2u);
}

}  // namespace
}  // namespace hemm::net

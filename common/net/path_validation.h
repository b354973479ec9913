// Path validation of the robot's stream channel, without sockets: which
// address the robot sends its streams to.
//
// The robot learns the operator's UDP endpoint from the traffic (a relay or
// a NAT may sit in between, so the TCP peer's address does not tell it), but
// an authenticated datagram proves only that its *content* is genuine, not
// that the operator sits at its source address: anyone who sees a datagram
// can send a copy from elsewhere, ahead of the original. So a source address
// becomes the peer only after a PathChallenge sent *to that address* came
// back answered (PathResponse with the challenge's random token, RFC 9000
// section 8.2 style). The challenge is sealed, so only the holder of the
// session keys can read the token: a copier never can.
//
// When a challenge is sent:
//   * no address validated yet (session start): to the source of any
//     authenticated datagram, rate-limited;
//   * an address validated: only after it has been silent (no authenticated
//     datagram from it, duplicates included) for `quiet_ns`. While the
//     validated path carries traffic, copies from other addresses are counted
//     (`ignored`) and get nothing at all, not even a challenge. A genuine
//     operator that moved (NAT rebinding, new interface) has gone silent on
//     its old address, so it is challenged and validated within about one
//     round trip after the quiet time.
// Duplicates nominate too: an attacker racing every datagram makes every
// original a duplicate, and the genuine path must still win; nominating costs
// only a rate-limited challenge that no one but the key holder can answer.
//
// When a response switches the path: only while the validated path is still
// silent (quiet_ns) when the response arrives. Someone on the path (a
// forwarder that copies datagrams) can earn a token in a short gap of the
// operator's traffic, by sending a copy from a second address, and get the
// operator to answer it later by passing the challenge on; a response that
// comes while the genuine path carries traffic again is refused (counted,
// and its token is used up), so a token is worth something only during the
// silence it was earned in. Tokens also live only 4 round trips, within
// [token_min_ns, token_max_ns]: the link's measured round trip (rtt_ns, set
// by the stream link), else the one the session's first validation took
// (challenge to response), else, before any, token_max_ns; not the seconds
// an attacker would like to hold them for.
//
// Limits: per candidate address one challenge per retry interval (doubling up
// to max_retry_ns), at most one challenge per min_interval_ns in all, at most
// max_candidates candidates (least recently seen evicted) and max_tokens
// outstanding tokens (oldest evicted), tokens expire (above).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace hemm::net {

// A UDP source address as plain bytes (IPv4 as an IPv4-mapped IPv6 address).
struct PathAddress {
  std::array<uint8_t, 16> ip{};
  uint16_t port = 0;
  bool operator==(const PathAddress&) const = default;
};

inline constexpr size_t kPathTokenBytes = 16;
using PathToken = std::array<uint8_t, kPathTokenBytes>;

struct PathValidatorParams {
  int64_t quiet_ns = 250'000'000;
  // Re-challenge after this, doubling: short while the round trip is unknown
  // (a lost challenge or response costs little), ~2 round trips once known.
  int64_t first_retry_ns = 250'000'000;
  int64_t max_retry_ns = 8'000'000'000;
  int64_t rtt_ns = 0;  // the link's round trip (StreamLink sets it; 0: not measured)
  int64_t token_min_ns = 250'000'000;
  int64_t token_max_ns = 8'000'000'000;
  int64_t min_interval_ns = 20'000'000;
  size_t max_candidates = 8;
  size_t max_tokens = 16;
};

struct PathCounters {
  uint64_t challenges_sent = 0;
  uint64_t validated = 0;             // addresses validated (the first one included)
  // Robot: authenticated datagrams from another address while the peer was
  // alive. Operator: path challenges from an address it does not send to.
  uint64_t ignored = 0;
  uint64_t rate_limited = 0;          // challenges due but held back by min_interval_ns
  uint64_t responses_unmatched = 0;   // responses with an unknown, expired or malformed token
  uint64_t responses_refused = 0;     // live token, but the current path was not silent: nothing validated
};

class PathValidator {
 public:
  explicit PathValidator(PathValidatorParams p = {}) : p_(p) {}

  PathValidatorParams& params() { return p_; }
  // A new session: forgets the peer, candidates and tokens (counters stay).
  void reset();

  // An authenticated datagram (delivered, late or duplicate) from `from` at
  // local time now_ns. Returns a fresh token to send to `from` in a
  // PathChallenge when one is due.
  std::optional<PathToken> on_datagram(const PathAddress& from, int64_t now_ns);
  // An authenticated PathResponse: the address its token was sent to becomes
  // the peer (returned); nullopt if the token matches no live challenge, or
  // the current peer is not silent (quiet_ns) at now_ns (the token is used up).
  std::optional<PathAddress> on_response(std::span<const uint8_t> token, int64_t now_ns);

  const std::optional<PathAddress>& peer() const { return peer_; }
  // How long a token issued now lives (see the file comment).
  int64_t token_lifetime_ns() const;
  const PathCounters& counters() const { return c_; }

 private:
  struct Candidate {
    PathAddress addr;
    int64_t last_seen_ns = 0;
    int64_t next_challenge_ns = 0;
    int64_t retry_ns = 0;
  };
  struct Outstanding {
    PathToken token{};
    PathAddress addr;
    int64_t issued_ns = 0;
    int64_t expires_ns = 0;
  };

  PathValidatorParams p_;
  std::optional<PathAddress> peer_;
  int64_t peer_seen_ns_ = 0;
  int64_t path_rtt_ns_ = 0;  // challenge to response of the latest validation (0: none yet)
  bool challenged_any_ = false;
  int64_t last_challenge_ns_ = 0;
  std::vector<Candidate> candidates_;
  std::vector<Outstanding> tokens_;
  PathCounters c_;
};

}  // namespace hemm::net

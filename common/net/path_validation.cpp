#include "common/net/path_validation.h"

#include <algorithm>

#include "common/net/crypto.h"

namespace hemm::net {

int64_t PathValidator::token_lifetime_ns() const {
  const int64_t rtt = p_.rtt_ns > 0 ? p_.rtt_ns : path_rtt_ns_;
  if (rtt <= 0) return p_.token_max_ns;
  const int64_t lo = std::min(p_.token_min_ns, p_.token_max_ns);
  return std::clamp(rtt > p_.token_max_ns / 4 ? p_.token_max_ns : 4 * rtt, lo, p_.token_max_ns);
}

void PathValidator::reset() {
  path_rtt_ns_ = 0;
  peer_.reset();
  peer_seen_ns_ = 0;
  challenged_any_ = false;
  last_challenge_ns_ = 0;
  candidates_.clear();
  tokens_.clear();
}

std::optional<PathToken> PathValidator::on_datagram(const PathAddress& from, int64_t now) {
  if (peer_ && from == *peer_) {
    peer_seen_ns_ = now;
    return std::nullopt;
  }
  if (peer_ && now - peer_seen_ns_ < p_.quiet_ns) {
    // The validated path is alive: this is a copy (or a stray), not a move.
    ++c_.ignored;
    return std::nullopt;
  }
  auto it = std::find_if(candidates_.begin(), candidates_.end(), [&](const Candidate& c) { return c.addr == from; });
  if (it == candidates_.end()) {
    if (candidates_.size() >= std::max<size_t>(1, p_.max_candidates)) {
      candidates_.erase(std::min_element(candidates_.begin(), candidates_.end(), [](const auto& a, const auto& b) {
        return a.last_seen_ns < b.last_seen_ns;
      }));
    }
    candidates_.push_back(Candidate{from, now, now, std::max<int64_t>(1, p_.first_retry_ns)});
    it = candidates_.end() - 1;
  }
  it->last_seen_ns = now;
  if (now < it->next_challenge_ns) return std::nullopt;
  if (challenged_any_ && now - last_challenge_ns_ < p_.min_interval_ns) {
    ++c_.rate_limited;
    return std::nullopt;
  }
  Outstanding o;
  random_bytes(o.token.data(), o.token.size());
  o.addr = from;
  o.issued_ns = now;
  o.expires_ns = now + token_lifetime_ns();
  if (tokens_.size() >= std::max<size_t>(1, p_.max_tokens)) tokens_.erase(tokens_.begin());  // oldest first
  tokens_.push_back(o);
  it->next_challenge_ns = now + it->retry_ns;
  it->retry_ns = std::min(2 * it->retry_ns, std::max(p_.max_retry_ns, p_.first_retry_ns));
  challenged_any_ = true;
  last_challenge_ns_ = now;
  ++c_.challenges_sent;
  return o.token;
}

std::optional<PathAddress> PathValidator::on_response(std::span<const uint8_t> token, int64_t now) {
  if (token.size() != kPathTokenBytes) {
    ++c_.responses_unmatched;
    return std::nullopt;
  }
  // Compare against every live token (constant time each): no early exit
  // that would tell which one came close.
  auto match = tokens_.end();
  for (auto it = tokens_.begin(); it != tokens_.end(); ++it) {
    if (equal_constant_time(it->token, token) && now <= it->expires_ns) match = it;
  }
  if (match == tokens_.end()) {
    ++c_.responses_unmatched;
    return std::nullopt;
  }
  if (peer_ && now - peer_seen_ns_ < p_.quiet_ns) {
    // The path it would replace is alive: this answer was held for later.
    ++c_.responses_refused;
    tokens_.erase(match);
    return std::nullopt;
  }
  path_rtt_ns_ = std::max<int64_t>(1, now - match->issued_ns);
  peer_ = match->addr;
  peer_seen_ns_ = now;
  candidates_.clear();
  tokens_.clear();
  ++c_.validated;
  return peer_;
}

}  // namespace hemm::net

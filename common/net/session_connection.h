// One TCP session connection over Asio: length-prefixed frames (framing.h)
// in both directions, sealed with the session keys once secure() is called.
// All methods and callbacks run on the io_context's (network) thread.
//
// The write queue is bounded (max_queued_bytes(): four largest frames, at
// least 1 MiB): a peer that stops reading cannot make us buffer without end.
// A frame that does not fit fails the connection ("write queue full": the
// close handler runs, as for a read error), because a session peer that does
// not read is broken or hostile; dropping frames instead would silently lose
// acks and e-stop reports. The robot then ends the session (and stops); the
// operator re-opens it.
#pragma once

#include <asio.hpp>
#include <deque>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "common/clock/steady_clock.h"
#include "common/net/framing.h"
#include "common/net/handshake.h"

namespace hemm::net {

class SessionConnection : public std::enable_shared_from_this<SessionConnection> {
 public:
  // Clear frame payload (before secure()).
  using RawHandler = std::function<void(std::span<const uint8_t> payload)>;
  // Authenticated frame (after secure()).
  using FrameHandler = std::function<void(const wire::SessionFrame& frame)>;
  // Called once when the connection ends for any reason but close().
  using CloseHandler = std::function<void(const std::string& reason)>;

  // Before secure() frames are limited to kMaxHandshakeFrameBytes, after it
  // to max_frame_bytes (+ the tag).
  SessionConnection(asio::ip::tcp::socket socket, size_t max_frame_bytes);
  static constexpr size_t kMaxHandshakeFrameBytes = 4096;

  void start(RawHandler on_raw, FrameHandler on_frame, CloseHandler on_close);
  // Replaces the callbacks (e.g. when a handshaking connection becomes the session).
  void set_handlers(RawHandler on_raw, FrameHandler on_frame, CloseHandler on_close);
  // From now on frames are sealed/opened with these (the handshake's result).
  void secure(SessionSecrets secrets);
  bool is_secure() const { return tx_ != nullptr; }

  // Queues a clear frame payload.
  void send_raw(std::vector<uint8_t> payload);
  // Queues a sealed SessionFrame (requires secure()).
  void send(const wire::SessionFrame& f);
  // Closes after everything queued has been written (or at once on error).
  void close_after_send();
  // Closes at once; no callback.
  void close();
  bool is_open() const { return socket_.is_open() && !closed_; }
  size_t queued_bytes() const { return queued_bytes_; }
  size_t max_queued_bytes() const { return max_queued_bytes_; }

  std::string peer() const { return peer_; }

 private:
  void read();
  void write_next();
  void fail(const std::string& reason);

  asio::ip::tcp::socket socket_;
  size_t max_frame_bytes_;
  FrameDecoder decoder_;
  std::array<uint8_t, 16384> rbuf_{};
  std::deque<std::vector<uint8_t>> wq_;
  size_t queued_bytes_ = 0;
  size_t max_queued_bytes_;
  bool writing_ = false;
  bool close_when_drained_ = false;
  bool closed_ = false;
  std::unique_ptr<FrameSealer> tx_;
  std::unique_ptr<FrameOpener> rx_;
  RawHandler on_raw_;
  FrameHandler on_frame_;
  CloseHandler on_close_;
  std::string peer_;
};

using hemm::steady_now_ns;  // the time base of all wire time stamps

}  // namespace hemm::net

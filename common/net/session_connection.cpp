#include "common/net/session_connection.h"

#include <algorithm>
#include <chrono>

namespace hemm::net {


SessionConnection::SessionConnection(asio::ip::tcp::socket socket, size_t max_frame_bytes)
    : socket_(std::move(socket)),
      max_frame_bytes_(max_frame_bytes),
      decoder_(std::min(max_frame_bytes, kMaxHandshakeFrameBytes)),
      max_queued_bytes_(std::max<size_t>(size_t{1} << 20, 4 * (max_frame_bytes + kTagBytes + kFrameHeaderBytes))) {
  asio::error_code ec;
  auto ep = socket_.remote_endpoint(ec);
  peer_ = ec ? std::string("?") : ep.address().to_string() + ":" + std::to_string(ep.port());
  socket_.set_option(asio::ip::tcp::no_delay(true), ec);
}

void SessionConnection::start(RawHandler on_raw, FrameHandler on_frame, CloseHandler on_close) {
  on_raw_ = std::move(on_raw);
  on_frame_ = std::move(on_frame);
  on_close_ = std::move(on_close);
  read();
}

void SessionConnection::set_handlers(RawHandler on_raw, FrameHandler on_frame, CloseHandler on_close) {
  on_raw_ = std::move(on_raw);
  on_frame_ = std::move(on_frame);
  on_close_ = std::move(on_close);
}

void SessionConnection::secure(SessionSecrets secrets) {
  tx_ = std::move(secrets.tx);
  rx_ = std::move(secrets.rx);
  decoder_.set_max_frame_bytes(max_frame_bytes_ + kTagBytes);
}

void SessionConnection::read() {
  auto self = shared_from_this();
  socket_.async_read_some(asio::buffer(rbuf_), [this, self](const asio::error_code& ec, size_t n) {
    if (closed_) return;
    if (ec) {
      fail(ec == asio::error::eof ? "peer closed the connection" : "read error: " + ec.message());
      return;
    }
    decoder_.feed(std::span<const uint8_t>(rbuf_.data(), n));
    std::vector<uint8_t> payload;
    for (;;) {
      const auto st = decoder_.next(&payload);
      if (st == FrameDecoder::Status::kNeedMore) break;
      if (st == FrameDecoder::Status::kError) {
        fail("bad frame: " + decoder_.error());
        return;
      }
      if (rx_) {
        wire::SessionFrame f;
        if (!open_session_frame(*rx_, payload, &f)) {
          fail("session frame failed authentication");
          return;
        }
        if (on_frame_) on_frame_(f);
      } else if (on_raw_) {
        on_raw_(payload);
      }
      if (closed_) return;  // a handler closed us
    }
    read();
  });
}

void SessionConnection::send_raw(std::vector<uint8_t> payload) {
  if (closed_) return;
  std::vector<uint8_t> frame;
  encode_frame(payload, &frame);
  if (queued_bytes_ + frame.size() > max_queued_bytes_) {
    fail("write queue full (" + std::to_string(queued_bytes_) + " bytes): the peer is not reading");
    return;
  }
  queued_bytes_ += frame.size();
  wq_.push_back(std::move(frame));
  if (!writing_) write_next();
}

void SessionConnection::send(const wire::SessionFrame& f) {
  if (closed_ || !tx_) return;
  send_raw(seal_session_frame(*tx_, f));
}

void SessionConnection::write_next() {
  if (closed_) return;
  if (wq_.empty()) {
    writing_ = false;
    if (close_when_drained_) close();
    return;
  }
  writing_ = true;
  auto self = shared_from_this();
  asio::async_write(socket_, asio::buffer(wq_.front()), [this, self](const asio::error_code& ec, size_t) {
    if (closed_) return;
    if (ec) {
      fail("write error: " + ec.message());
      return;
    }
    queued_bytes_ -= wq_.front().size();
    wq_.pop_front();
    write_next();
  });
}

void SessionConnection::close_after_send() {
  if (closed_) return;
  close_when_drained_ = true;
  if (!writing_) close();
}

void SessionConnection::close() {
  if (closed_) return;
  closed_ = true;
  asio::error_code ec;
  socket_.shutdown(asio::ip::tcp::socket::shutdown_both, ec);
  socket_.close(ec);
  wq_.clear();
  queued_bytes_ = 0;
}

void SessionConnection::fail(const std::string& reason) {
  if (closed_) return;
  close();
  if (on_close_) {
    auto cb = std::move(on_close_);
    cb(reason);
  }
}

}  // namespace hemm::net

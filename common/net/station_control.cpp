#include "common/net/station_control.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>

namespace hemm::net {

namespace {
using local = asio::local::stream_protocol;
constexpr auto kConnectionTimeout = std::chrono::seconds(10);  // a client that sends nothing is dropped

// The request line without its end; nullopt if it is not printable ASCII.
std::optional<std::string> clean_line(std::string line) {
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r' || line.back() == ' ')) line.pop_back();
  const auto first = line.find_first_not_of(' ');
  line.erase(0, first == std::string::npos ? line.size() : first);
  if (line.empty()) return std::nullopt;
  for (char c : line)
    if (c < 0x20 || c > 0x7e) return std::nullopt;
  return line;
}
}  // namespace

struct ControlServer::Shared {
  asio::io_context& io;
  Handler handler;
  local::acceptor acceptor;
  std::uint64_t requests = 0, rejected = 0;
  Shared(asio::io_context& i, Handler h) : io(i), handler(std::move(h)), acceptor(i) {}
};

// One client connection: one line in, one line out.
struct ControlServer::Conn : std::enable_shared_from_this<Conn> {
  local::socket socket;
  asio::streambuf in{kMaxControlLine + 1};
  asio::steady_timer timer;
  std::string out;
  explicit Conn(asio::io_context& io) : socket(io), timer(io) {}
  void reply(const std::string& line) {
    out = line + "\n";
    auto self = shared_from_this();
    asio::async_write(socket, asio::buffer(out), [self](const asio::error_code&, std::size_t) {
      asio::error_code ignored;
      self->socket.shutdown(local::socket::shutdown_both, ignored);
      self->socket.close(ignored);
      self->timer.cancel();
    });
  }
};

ControlServer::ControlServer(asio::io_context& io, std::string path, Handler handler)
    : io_(io), path_(std::move(path)), sh_(std::make_shared<Shared>(io, std::move(handler))) {}

ControlServer::~ControlServer() { stop(); }

std::uint64_t ControlServer::requests() const { return sh_->requests; }
std::uint64_t ControlServer::rejected() const { return sh_->rejected; }

bool ControlServer::start(std::string* error) {
  if (path_.empty() || path_.size() >= sizeof(sockaddr_un::sun_path)) {
    *error = "control socket path must be 1.." + std::to_string(sizeof(sockaddr_un::sun_path) - 1) + " bytes";
    return false;
  }
  struct stat st {};
  if (::lstat(path_.c_str(), &st) == 0) {
    if (!S_ISSOCK(st.st_mode)) {
      *error = "control socket path " + path_ + " exists and is not a socket";
      return false;
    }
    local::socket probe(io_);
    asio::error_code ec;
    probe.connect(local::endpoint(path_), ec);
    if (!ec) {
      *error = "a station already listens on control socket " + path_;
      return false;
    }
    ::unlink(path_.c_str());  // left by a station that died
  }
  local::acceptor& acceptor = sh_->acceptor;
  asio::error_code ec;
  acceptor.open(local(), ec);
  if (!ec) acceptor.bind(local::endpoint(path_), ec);
  if (ec) {
    *error = "control socket " + path_ + ": " + ec.message();
    acceptor.close(ec);
    return false;
  }
  bound_ = true;
  // Owner only, before anything can connect (connecting needs listen()).
  if (::chmod(path_.c_str(), S_IRUSR | S_IWUSR) != 0) {
    *error = "control socket " + path_ + ": cannot make it owner-only";
    stop();
    return false;
  }
  acceptor.listen(8, ec);
  if (ec) {
    *error = "control socket " + path_ + ": " + ec.message();
    stop();
    return false;
  }
  accept(sh_);
  return true;
}

void ControlServer::stop() {
  asio::error_code ec;
  sh_->acceptor.close(ec);
  if (bound_) ::unlink(path_.c_str());
  bound_ = false;
}

void ControlServer::accept(const std::shared_ptr<Shared>& sh) {
  auto conn = std::make_shared<Conn>(sh->io);
  sh->acceptor.async_accept(conn->socket, [sh, conn](const asio::error_code& ec) {
    if (ec == asio::error::operation_aborted || !sh->acceptor.is_open()) return;
    if (!ec) {
      conn->timer.expires_after(kConnectionTimeout);
      conn->timer.async_wait([conn](const asio::error_code& tec) {
        if (!tec) {
          asio::error_code ignored;
          conn->socket.close(ignored);
        }
      });
      asio::async_read_until(conn->socket, conn->in, '\n', [sh, conn](const asio::error_code& rec, std::size_t) {
        if (rec && rec != asio::error::eof) {
          if (rec != asio::error::operation_aborted) {
            ++sh->rejected;
            conn->reply("error request longer than " + std::to_string(kMaxControlLine) + " bytes");
          }
          return;
        }
        std::string line(asio::buffers_begin(conn->in.data()), asio::buffers_end(conn->in.data()));
        const auto nl = line.find('\n');
        if (nl != std::string::npos) line.resize(nl);
        const auto cmd = clean_line(line);
        if (!cmd || !sh->acceptor.is_open()) {
          ++sh->rejected;
          conn->reply(cmd ? "error the station is stopping" : "error empty or non-printable request");
          return;
        }
        ++sh->requests;
        sh->handler(*cmd, [conn](const std::string& reply) { conn->reply(reply); });
      });
    }
    accept(sh);
  });
}

std::optional<std::string> control_request(const std::string& path, const std::string& command,
                                           std::chrono::milliseconds timeout, std::string* error) {
  asio::io_context io;
  local::socket socket(io);
  asio::streambuf in(kMaxControlLine * 4);
  const std::string out = command + "\n";
  std::optional<std::string> reply;
  std::string fail;
  socket.async_connect(local::endpoint(path), [&](const asio::error_code& ec) {
    if (ec) {
      fail = "cannot connect to control socket " + path + ": " + ec.message();
      return;
    }
    asio::async_write(socket, asio::buffer(out), [&](const asio::error_code& wec, std::size_t) {
      if (wec) {
        fail = "control socket " + path + ": " + wec.message();
        return;
      }
      asio::async_read_until(socket, in, '\n', [&](const asio::error_code& rec, std::size_t) {
        if (rec && rec != asio::error::eof) {
          fail = "control socket " + path + ": " + rec.message();
          return;
        }
        std::string line(asio::buffers_begin(in.data()), asio::buffers_end(in.data()));
        const auto nl = line.find('\n');
        if (nl == std::string::npos) {
          fail = "control socket " + path + ": the station closed without a reply";
          return;
        }
        line.resize(nl);
        reply = line;
      });
    });
  });
  io.run_for(timeout);
  if (reply) return reply;
  *error = fail.empty() ? "no reply from control socket " + path + " within " +
                              std::to_string(timeout.count()) + " ms"
                        : fail;
  return std::nullopt;
}

}  // namespace hemm::net

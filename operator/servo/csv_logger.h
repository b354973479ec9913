// A real-time-safe CSV logger: the producer (servo thread) pushes fixed-size
// records into a preallocated SPSC ring and never blocks (a full ring drops
// the record and counts it); a writer thread drains the ring into a CSV file
// with a header line. The record type and its formatting are parameters.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>
#include <thread>

#include "operator/servo/spsc_ring.h"

namespace hemm::servo {

template <class T>
class CsvLogger {
 public:
  // Writes one record as a CSV line (with '\n') into buf; returns its length,
  // 0 if it does not fit.
  using FormatFn = std::size_t (*)(const T&, char* buf, std::size_t size);
  static constexpr std::size_t kLineMax = 4096;

  CsvLogger(std::size_t capacity, std::string header, FormatFn format)
      : ring_(capacity), header_(std::move(header)), format_(format) {}
  CsvLogger(const CsvLogger&) = delete;
  CsvLogger& operator=(const CsvLogger&) = delete;
  ~CsvLogger() { stop(); }

  // Opens `path` (truncating), writes the header and starts the writer thread.
  // Returns an error message and starts nothing if the file cannot be opened
  // or the logger already runs.
  std::optional<std::string> start(const std::string& path) {
    if (thread_.joinable()) return std::string("logger already running");
    std::FILE* f = std::fopen(path.c_str(), "w");
    if (f == nullptr) return "cannot open " + path + " for writing";
    if (std::fprintf(f, "%s\n", header_.c_str()) < 0) {
      std::fclose(f);
      return "cannot write to " + path;
    }
    file_ = f;
    stop_.store(false, std::memory_order_relaxed);
    thread_ = std::thread([this] { run(); });
    return std::nullopt;
  }

  // Drains what is left, closes the file, joins the writer. Idempotent.
  void stop() {
    if (!thread_.joinable()) return;
    stop_.store(true, std::memory_order_release);
    thread_.join();
  }

  // Producer side: never blocks; false (and counted) if the ring is full.
  bool push(const T& record) noexcept {
    if (ring_.try_push(record)) return true;
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }

  std::uint64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }
  std::uint64_t written() const noexcept { return written_.load(std::memory_order_relaxed); }
  bool write_failed() const noexcept { return write_failed_.load(std::memory_order_relaxed); }
  std::size_t capacity() const noexcept { return ring_.capacity(); }
  const std::string& header() const noexcept { return header_; }

 private:
  void drain() {
    T rec{};
    char line[kLineMax];
    while (ring_.try_pop(rec)) {
      const std::size_t n = format_(rec, line, sizeof line);
      if (n == 0 || std::fwrite(line, 1, n, file_) != n) write_failed_.store(true);
      written_.fetch_add(1, std::memory_order_relaxed);
    }
  }
  void run() {
    while (!stop_.load(std::memory_order_acquire)) {
      drain();
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    drain();
    if (std::fclose(file_) != 0) write_failed_.store(true);
    file_ = nullptr;
  }

  SpscRing<T> ring_;
  std::string header_;
  FormatFn format_;
  std::FILE* file_ = nullptr;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> dropped_{0}, written_{0};
  std::atomic<bool> write_failed_{false};
};

}  // namespace hemm::servo

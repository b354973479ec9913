// Formats one CSV row of numbers into a caller's buffer without allocating
// (the writer threads of the servo log and the trajectory recorder format a
// row per servo tick). Numbers are written in shortest round-trip form, so
// parsing gives back the same values.
#pragma once

#include <charconv>
#include <cstddef>
#include <iterator>

namespace hemm::device {

class CsvRowWriter {
 public:
  CsvRowWriter(char* buf, std::size_t size) : begin_(buf), p_(buf), end_(buf + size) {}

  // Appends v and a separator; after an overflow every call is a no-op.
  template <class V>
  void put(V v) noexcept {
    if (p_ == nullptr) return;
    const auto r = std::to_chars(p_, end_, v);
    if (r.ec != std::errc() || r.ptr == end_) {
      p_ = nullptr;
      return;
    }
    p_ = r.ptr;
    *p_++ = ',';
  }
  // Each element of an Eigen vector or a plain array.
  template <class Vec>
  void put_vector(const Vec& v) noexcept {
    for (std::size_t i = 0; i < static_cast<std::size_t>(std::size(v)); ++i) put(v[i]);
  }

  // Turns the last separator into the line end. Returns the row's length
  // with '\n', 0 if it overflowed or is empty.
  std::size_t finish() noexcept {
    if (p_ == nullptr || p_ == begin_) return 0;
    p_[-1] = '\n';
    return static_cast<std::size_t>(p_ - begin_);
  }

 private:
  char* begin_;
  char* p_;
  char* end_;
};

}  // namespace hemm::device

// Counts heap allocations and frees made by threads that opted in (the servo
// thread in servo_loop_test). The replacement operator new/delete (and, outside
// sanitizer builds, malloc/calloc/realloc/free) live in alloc_counter.cpp.
#pragma once

#include <cstdint>

namespace hemm::test {

// Start/stop counting allocations made by the calling thread.
void count_allocations_on_this_thread(bool on) noexcept;
// Allocations made by counting threads so far.
std::uint64_t counted_allocations() noexcept;
// Frees (free, operator delete; null pointers not counted) by counting threads so far.
std::uint64_t counted_frees() noexcept;
// True if malloc itself is hooked (not only operator new).
bool malloc_is_hooked() noexcept;

}  // namespace hemm::test

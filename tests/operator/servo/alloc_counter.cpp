#include "tests/operator/servo/alloc_counter.h"

#include <atomic>
#include <cstdlib>
#include <new>

namespace {
thread_local bool t_counting = false;
std::atomic<std::uint64_t> g_counted{0};
std::atomic<std::uint64_t> g_frees{0};

inline void note() noexcept {
  if (t_counting) g_counted.fetch_add(1, std::memory_order_relaxed);
}
// A free on the servo thread is as bad as an allocation (it takes the
// allocator's locks, and means something was retired on the wrong thread).
inline void note_free(const void* p) noexcept {
  if (t_counting && p != nullptr) g_frees.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

namespace hemm::test {
void count_allocations_on_this_thread(bool on) noexcept { t_counting = on; }
std::uint64_t counted_allocations() noexcept { return g_counted.load(); }
std::uint64_t counted_frees() noexcept { return g_frees.load(); }
#ifdef HEMM_SANITIZE
bool malloc_is_hooked() noexcept { return false; }
#else
bool malloc_is_hooked() noexcept { return true; }
#endif
}  // namespace hemm::test

#ifndef HEMM_SANITIZE
// glibc lets the executable interpose malloc; forward to its real allocator.
// (Under ASan the sanitizer owns malloc, so only operator new is counted.)
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void __libc_free(void*);
void* __libc_memalign(std::size_t, std::size_t);

void* malloc(std::size_t n) {
  note();
  return __libc_malloc(n);
}
void* calloc(std::size_t a, std::size_t b) {
  note();
  return __libc_calloc(a, b);
}
void* realloc(void* p, std::size_t n) {
  note();
  return __libc_realloc(p, n);
}
void free(void* p) {
  note_free(p);
  __libc_free(p);
}
void* aligned_alloc(std::size_t al, std::size_t n) {
  note();
  return __libc_memalign(al, n);
}
int posix_memalign(void** out, std::size_t al, std::size_t n) {
  note();
  void* p = __libc_memalign(al, n);
  if (p == nullptr) return 12;  // ENOMEM
  *out = p;
  return 0;
}
void* memalign(std::size_t al, std::size_t n) {
  note();
  return __libc_memalign(al, n);
}
}
#endif

// operator new/delete: counted in every build. They allocate through malloc
// directly (not counted twice: the malloc hook only counts, but operator new
// is the place a C++ allocation is attributed to).
namespace {
void* counted_new(std::size_t n) {
  note();
  const bool was = t_counting;
  t_counting = false;  // avoid counting the same allocation again in malloc
  void* p = std::malloc(n == 0 ? 1 : n);
  t_counting = was;
  if (p == nullptr) throw std::bad_alloc();
  return p;
}
void* counted_new_aligned(std::size_t n, std::align_val_t al) {
  note();
  const bool was = t_counting;
  t_counting = false;
  void* p = std::aligned_alloc(static_cast<std::size_t>(al),
                               (n + static_cast<std::size_t>(al) - 1) & ~(static_cast<std::size_t>(al) - 1));
  t_counting = was;
  if (p == nullptr) throw std::bad_alloc();
  return p;
}
// Counted once here, not again in the free() hook.
void counted_delete(void* p) noexcept {
  note_free(p);
  const bool was = t_counting;
  t_counting = false;
  std::free(p);
  t_counting = was;
}
}  // namespace

void* operator new(std::size_t n) { return counted_new(n); }
void* operator new[](std::size_t n) { return counted_new(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return counted_new(n);
  } catch (...) {
    return nullptr;
  }
}
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return counted_new(n);
  } catch (...) {
    return nullptr;
  }
}
void* operator new(std::size_t n, std::align_val_t al) { return counted_new_aligned(n, al); }
void* operator new[](std::size_t n, std::align_val_t al) { return counted_new_aligned(n, al); }
void operator delete(void* p) noexcept { counted_delete(p); }
void operator delete[](void* p) noexcept { counted_delete(p); }
void operator delete(void* p, std::size_t) noexcept { counted_delete(p); }
void operator delete[](void* p, std::size_t) noexcept { counted_delete(p); }
void operator delete(void* p, std::align_val_t) noexcept { counted_delete(p); }
void operator delete[](void* p, std::align_val_t) noexcept { counted_delete(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { counted_delete(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { counted_delete(p); }

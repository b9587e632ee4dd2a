#pragma once
// =================================================================================================
// INCLUDE THIS HEADER IN EXACTLY ONE TRANSLATION UNIT PER TEST EXECUTABLE.
//
// It DEFINES (not just declares) the global allocation functions of the program: malloc, calloc,
// realloc and free (forwarding to glibc's __libc_*), and the replaceable global operator new,
// new[] and every operator delete / delete[] (plain, sized, nothrow). A second translation unit
// of the same executable including it is a multiple-definition link error.
// =================================================================================================
//
// Heap-allocation counters for "does not allocate" tests. While an AllocationCounter is running,
// every malloc/calloc/realloc call and every operator new/new[] call in the process (any thread)
// is counted; mallocs and news are counted separately. Eigen allocates with std::malloc, OpenCV and
// glibc internals too, so hooking operator new alone would not see them.
//
// The hooks are compiled out when a sanitizer that interposes malloc is detected (ASan, TSan,
// MSan, HWASan: they own malloc, and a second definition crashes or conflicts) or when the C
// library is not glibc (no __libc_malloc). allocation_counting_available() is false then, the
// counters stay at zero, and tests that rely on counting must GTEST_SKIP():
//
//   if (!sinew::testing::allocation_counting_available())
//     GTEST_SKIP() << sinew::testing::kAllocationCountingUnavailable;
//   sinew::testing::AllocationCounter counter;  // counting from here ...
//   code_under_test();
//   counter.stop();                              // ... to here (or to the end of the scope)
//   EXPECT_EQ(counter.total(), 0);
//
// Aligned operator new (std::align_val_t), posix_memalign, aligned_alloc and memalign are not
// hooked.
#include <atomic>
#include <cstddef>
#include <cstdlib>  // glibc's <stdlib.h> pulls in <features.h>, which defines __GLIBC__
#include <new>

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__) || defined(__SANITIZE_HWADDRESS__)
#define SINEW_ALLOCATION_COUNTER_UNDER_SANITIZER 1
#endif
#if defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(memory_sanitizer) || __has_feature(hwaddress_sanitizer)
#define SINEW_ALLOCATION_COUNTER_UNDER_SANITIZER 1
#endif
#endif

#if defined(__GLIBC__) && !defined(SINEW_ALLOCATION_COUNTER_UNDER_SANITIZER)
#define SINEW_ALLOCATION_COUNTER_HOOKS 1
#else
#define SINEW_ALLOCATION_COUNTER_HOOKS 0
#endif

namespace sinew::testing {

/// True when the hooks are compiled in; false under sanitizers and without glibc.
constexpr bool allocation_counting_available() noexcept {
  return SINEW_ALLOCATION_COUNTER_HOOKS != 0;
}

/// Skip message for tests that rely on counting.
inline constexpr char kAllocationCountingUnavailable[] =
    "allocation counting is compiled out (sanitizer build or not glibc)";

namespace allocation_counter_detail {
// Constant-initialised, so usable by allocations made before dynamic initialisation.
inline std::atomic<bool> counting{false};
inline std::atomic<long> mallocs{0};
inline std::atomic<long> news{0};

inline void count(std::atomic<long>& counter) noexcept {
  if (counting.load(std::memory_order_relaxed)) counter.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace allocation_counter_detail

/// Counts allocations from construction until stop() or destruction, then keeps the counts.
/// One at a time: the counts are process-wide, and starting a counter resets them, so counters
/// must not be nested or overlap.
class AllocationCounter {
 public:
  AllocationCounter() noexcept {
    namespace d = allocation_counter_detail;
    d::mallocs.store(0);
    d::news.store(0);
    d::counting.store(true);
  }
  ~AllocationCounter() { stop(); }
  AllocationCounter(const AllocationCounter&) = delete;
  AllocationCounter& operator=(const AllocationCounter&) = delete;

  /// Stops counting and freezes mallocs(), news() and total(). Idempotent.
  void stop() noexcept {
    if (!running_) return;
    namespace d = allocation_counter_detail;
    d::counting.store(false);
    mallocs_ = d::mallocs.load();
    news_ = d::news.load();
    running_ = false;
  }

  /// malloc, calloc and realloc calls so far (live while running).
  long mallocs() const noexcept {
    return running_ ? allocation_counter_detail::mallocs.load() : mallocs_;
  }
  /// operator new and new[] calls so far (live while running).
  long news() const noexcept { return running_ ? allocation_counter_detail::news.load() : news_; }
  long total() const noexcept { return mallocs() + news(); }

 private:
  bool running_ = true;
  long mallocs_ = 0;
  long news_ = 0;
};

}  // namespace sinew::testing

#if SINEW_ALLOCATION_COUNTER_HOOKS
extern "C" {
void* __libc_malloc(std::size_t) noexcept;
void* __libc_calloc(std::size_t, std::size_t) noexcept;
void* __libc_realloc(void*, std::size_t) noexcept;
void __libc_free(void*) noexcept;

void* malloc(std::size_t n) noexcept {
  sinew::testing::allocation_counter_detail::count(
      sinew::testing::allocation_counter_detail::mallocs);
  return __libc_malloc(n);
}
void* calloc(std::size_t n, std::size_t m) noexcept {
  sinew::testing::allocation_counter_detail::count(
      sinew::testing::allocation_counter_detail::mallocs);
  return __libc_calloc(n, m);
}
void* realloc(void* p, std::size_t n) noexcept {
  sinew::testing::allocation_counter_detail::count(
      sinew::testing::allocation_counter_detail::mallocs);
  return __libc_realloc(p, n);
}
void free(void* p) noexcept {
  __libc_free(p);
}
}  // extern "C"

void* operator new(std::size_t n) {
  sinew::testing::allocation_counter_detail::count(sinew::testing::allocation_counter_detail::news);
  if (void* p = __libc_malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) {
  sinew::testing::allocation_counter_detail::count(sinew::testing::allocation_counter_detail::news);
  if (void* p = __libc_malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  sinew::testing::allocation_counter_detail::count(sinew::testing::allocation_counter_detail::news);
  return __libc_malloc(n ? n : 1);
}
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept {
  sinew::testing::allocation_counter_detail::count(sinew::testing::allocation_counter_detail::news);
  return __libc_malloc(n ? n : 1);
}
void operator delete(void* p) noexcept {
  __libc_free(p);
}
void operator delete[](void* p) noexcept {
  __libc_free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  __libc_free(p);
}
void operator delete[](void* p, std::size_t) noexcept {
  __libc_free(p);
}
void operator delete(void* p, const std::nothrow_t&) noexcept {
  __libc_free(p);
}
void operator delete[](void* p, const std::nothrow_t&) noexcept {
  __libc_free(p);
}
#endif  // SINEW_ALLOCATION_COUNTER_HOOKS

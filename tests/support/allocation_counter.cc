#include "allocation_counter.h"
#include "sanitizers.h"

#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstdlib>
#include <new>

// Every heap allocation of the process is counted: C++'s operator new, and the C allocator that Eigen's
// dynamic-size temporaries use (std::malloc, or calloc when the compiler merges a malloc with the zeroing
// that follows it). The C functions are interposed (glibc lets a program define them) and forward to
// glibc's own implementation, so free() stays glibc's. Under AddressSanitizer (scripts/sanitize.sh), which
// owns the C allocator, only operator new is counted.
#if MOREAU_UNDER_ASAN
#define MOREAU_COUNT_C_ALLOCATOR 0
#else
#define MOREAU_COUNT_C_ALLOCATOR 1
#endif

namespace {
std::atomic<long> g_allocations{0};
}

#if MOREAU_COUNT_C_ALLOCATOR
extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t count, std::size_t size);
void* __libc_realloc(void* p, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);

void* malloc(std::size_t size) {
  ++g_allocations;
  return __libc_malloc(size);
}
void* calloc(std::size_t count, std::size_t size) {
  ++g_allocations;
  return __libc_calloc(count, size);
}
void* realloc(void* p, std::size_t size) {
  ++g_allocations;
  return __libc_realloc(p, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) {
  ++g_allocations;
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) {
  ++g_allocations;
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
}
#endif

void* operator new(std::size_t size) {
  if (!MOREAU_COUNT_C_ALLOCATOR) ++g_allocations;  // otherwise malloc counts it
  if (void* p = std::malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace moreau::testing {
long allocations() { return g_allocations.load(); }
}  // namespace moreau::testing

// MOREAU_UNDER_ASAN: 1 when this translation unit is built with AddressSanitizer, by GCC (which defines
// __SANITIZE_ADDRESS__) or by clang (which says so through __has_feature(address_sanitizer)), else 0.
// Tests that limit a child's address space, or count the C allocator's calls, must know: ASan's shadow
// memory needs terabytes of address space, and ASan owns malloc.
#pragma once

#if defined(__SANITIZE_ADDRESS__)
#define MOREAU_UNDER_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define MOREAU_UNDER_ASAN 1
#endif
#endif
#ifndef MOREAU_UNDER_ASAN
#define MOREAU_UNDER_ASAN 0
#endif

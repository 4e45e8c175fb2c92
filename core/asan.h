// MJSYSID_ASAN is defined (as 1) when the translation unit is compiled with AddressSanitizer, by
// gcc (__SANITIZE_ADDRESS__) or clang (__has_feature(address_sanitizer)): code that must behave
// differently under it (its shadow memory counts as address space; libraries that keep memory
// until exit) tests this one macro.
#pragma once

#if defined(__SANITIZE_ADDRESS__)
#define MJSYSID_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define MJSYSID_ASAN 1
#endif
#endif

// Broken invariants: see core/invariant.h.
#include "core/invariant.h"

#include <cstdio>
#include <cstdlib>

namespace mjsysid {

void BrokenInvariant(const char* what, const char* file, int line) {
  std::fprintf(stderr, "mjsysid: broken invariant: %s (%s:%d)\n", what, file, line);
  std::fflush(stderr);
  std::abort();
}

}  // namespace mjsysid

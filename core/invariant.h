// Broken invariants: a condition the code itself guarantees (never one that user input can break:
// that is an exception with a message, core/mujoco_env.h). When it fails the process stops at once
// with the message on stderr, the one place in core/ and sysid/ that writes there (Drake's
// DRAKE_DEMAND): continuing would compute on state that is known to be wrong.
#pragma once

namespace mjsysid {

// writes "mjsysid: broken invariant: WHAT (FILE:LINE)" to stderr and aborts
[[noreturn]] void BrokenInvariant(const char* what, const char* file, int line);

}  // namespace mjsysid

// aborts through BrokenInvariant unless cond holds; what: a string literal saying what broke
#define MJSYSID_DEMAND(cond, what)                                     \
  do {                                                                 \
    if (!(cond)) ::mjsysid::BrokenInvariant(what, __FILE__, __LINE__); \
  } while (0)

// The content hash of a file: SHA-256 (OpenSSL's libcrypto, already a dependency of libhdf5-dev),
// as 64 lowercase hex digits. Used to record which inputs a fit read (sysid/run/input_hashes.h).
#pragma once

#include <optional>
#include <string>

namespace mjsysid::io {

// the SHA-256 of the file's bytes as lowercase hex; nullopt when it cannot be opened or read
std::optional<std::string> FileSha256(const std::string& path);

}  // namespace mjsysid::io

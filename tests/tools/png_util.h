// PNG bytes decoded with cairo (libpng underneath: signature, chunk CRCs, zlib stream), for the
// report tests.
#pragma once

#include <cairo.h>

#include <algorithm>
#include <string>

namespace mjsysid::test {

// a cairo image surface of the PNG in `bytes` (check cairo_surface_status; the caller destroys it)
inline cairo_surface_t* SurfaceFromPng(const std::string& bytes) {
  struct Reader {
    const std::string* bytes;
    size_t at = 0;
  } reader{&bytes};
  auto read = [](void* closure, unsigned char* data, unsigned int length) {
    auto* r = static_cast<Reader*>(closure);
    if (r->bytes->size() - r->at < length) return CAIRO_STATUS_READ_ERROR;
    std::copy_n(r->bytes->data() + r->at, length, data);
    r->at += length;
    return CAIRO_STATUS_SUCCESS;
  };
  return cairo_image_surface_create_from_png_stream(read, &reader);
}

}  // namespace mjsysid::test

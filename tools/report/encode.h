// Animated WebP (libwebp's WebPAnimEncoder / WebPAnimDecoder, Debian's libwebp-dev): the report's
// motion clips, embedded in the page as data:image/webp URIs that browsers play in an <img>.
//
// Contract:
// - EncodeAnimatedWebp: frames of one size (RgbImage, tools/report/render.h), each shown
//   frame_ms milliseconds, looping forever; lossy at `quality` (0..100). Returns the file's bytes.
//   Throws std::invalid_argument for no frames or frames of different sizes, std::runtime_error
//   when libwebp fails.
// - DecodeAnimatedWebp: the frames back as RGB (for tests and checks), with their count, size and
//   timestamps; throws std::runtime_error when the bytes are not an animated WebP.
#pragma once

#include <string>
#include <vector>

#include "tools/report/render.h"

namespace mjsysid::report {

std::string EncodeAnimatedWebp(const std::vector<RgbImage>& frames, int frame_ms,
                               float quality = 70);

struct DecodedAnimation {
  int width = 0, height = 0;
  int loop_count = 0;            // 0: forever
  std::vector<RgbImage> frames;  // fully composed frames
  std::vector<int> end_ms;       // per frame: the time it ends (ms since the start)
};
DecodedAnimation DecodeAnimatedWebp(const std::string& bytes);

}  // namespace mjsysid::report

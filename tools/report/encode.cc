#include "tools/report/encode.h"

#include <webp/demux.h>
#include <webp/encode.h>
#include <webp/mux.h>

#include <algorithm>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace mjsysid::report {
namespace {

struct EncoderDeleter {
  void operator()(WebPAnimEncoder* e) const { WebPAnimEncoderDelete(e); }
};
struct DecoderDeleter {
  void operator()(WebPAnimDecoder* d) const { WebPAnimDecoderDelete(d); }
};
struct PictureFree {
  void operator()(WebPPicture* p) const { WebPPictureFree(p); }
};

}  // namespace

std::string EncodeAnimatedWebp(const std::vector<RgbImage>& frames, int frame_ms, float quality) {
  if (frames.empty()) throw std::invalid_argument("EncodeAnimatedWebp: no frames");
  const int w = frames[0].width, h = frames[0].height;
  for (const RgbImage& f : frames) {
    if (f.width != w || f.height != h || f.rgb.size() != static_cast<size_t>(w) * h * 3) {
      throw std::invalid_argument("EncodeAnimatedWebp: frames of different sizes");
    }
  }

  // the encoder: loop forever, key frames chosen by libwebp
  WebPAnimEncoderOptions anim;
  if (!WebPAnimEncoderOptionsInit(&anim)) throw std::runtime_error("libwebp: version mismatch");
  anim.anim_params.loop_count = 0;
  std::unique_ptr<WebPAnimEncoder, EncoderDeleter> enc(WebPAnimEncoderNew(w, h, &anim));
  if (!enc) throw std::runtime_error("libwebp: WebPAnimEncoderNew failed");
  WebPConfig config;
  if (!WebPConfigInit(&config)) throw std::runtime_error("libwebp: version mismatch");
  config.quality = quality;
  config.method = 4;

  // each frame at its timestamp, then the end time of the last one
  WebPPicture picture;
  if (!WebPPictureInit(&picture)) throw std::runtime_error("libwebp: version mismatch");
  picture.width = w;
  picture.height = h;
  std::unique_ptr<WebPPicture, PictureFree> owned(&picture);
  int timestamp = 0;
  for (const RgbImage& f : frames) {
    if (!WebPPictureImportRGB(&picture, f.rgb.data(), w * 3) ||
        !WebPAnimEncoderAdd(enc.get(), &picture, timestamp, &config)) {
      throw std::runtime_error(std::string("libwebp: adding a frame failed: ") +
                               WebPAnimEncoderGetError(enc.get()));
    }
    timestamp += frame_ms;
  }
  WebPData data;
  WebPDataInit(&data);
  if (!WebPAnimEncoderAdd(enc.get(), nullptr, timestamp, nullptr) ||
      !WebPAnimEncoderAssemble(enc.get(), &data)) {
    throw std::runtime_error(std::string("libwebp: assembling the animation failed: ") +
                             WebPAnimEncoderGetError(enc.get()));
  }
  std::string bytes(reinterpret_cast<const char*>(data.bytes), data.size);
  WebPDataClear(&data);
  return bytes;
}

DecodedAnimation DecodeAnimatedWebp(const std::string& bytes) {
  WebPData data = {reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()};
  WebPAnimDecoderOptions options;
  if (!WebPAnimDecoderOptionsInit(&options)) throw std::runtime_error("libwebp: version mismatch");
  options.color_mode = MODE_RGBA;  // the animation decoder has no RGB mode
  options.use_threads = 0;
  std::unique_ptr<WebPAnimDecoder, DecoderDeleter> dec(WebPAnimDecoderNew(&data, &options));
  if (!dec) throw std::runtime_error("not an animated WebP");
  WebPAnimInfo info;
  if (!WebPAnimDecoderGetInfo(dec.get(), &info)) throw std::runtime_error("WebP: no info");

  DecodedAnimation out;
  out.width = static_cast<int>(info.canvas_width);
  out.height = static_cast<int>(info.canvas_height);
  out.loop_count = static_cast<int>(info.loop_count);
  const size_t pixels = static_cast<size_t>(out.width) * out.height;
  while (WebPAnimDecoderHasMoreFrames(dec.get())) {
    uint8_t* rgba = nullptr;
    int timestamp = 0;
    if (!WebPAnimDecoderGetNext(dec.get(), &rgba, &timestamp)) {
      throw std::runtime_error("WebP: a frame could not be decoded");
    }
    RgbImage frame{out.width, out.height, std::vector<uint8_t>(pixels * 3)};
    for (size_t i = 0; i < pixels; ++i) std::copy_n(rgba + 4 * i, 3, frame.rgb.data() + 3 * i);
    out.frames.push_back(std::move(frame));
    out.end_ms.push_back(timestamp);
  }
  return out;
}

}  // namespace mjsysid::report

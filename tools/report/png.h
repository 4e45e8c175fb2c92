// A small RGB raster image with anti-aliased drawing, a built-in bitmap font, and a PNG encoder.
//
// - Coordinates are pixels, x to the right, y down; pixel (x, y) covers [x, x+1) x [y, y+1).
// - Every drawing call is clipped to the clip rectangle (the whole image unless SetClip).
// - The font is a 5x9 bitmap (rows 0-6 above the baseline, 7-8 for descenders) covering printable
//   ASCII; other bytes draw as '?' (one per UTF-8 character). At scale s a character advances
//   6s pixels and a line is 11s pixels tall.
// - EncodePng writes 8-bit RGB, no interlace, filter type 0 on every row, one zlib IDAT chunk.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace mjsysid::report {

struct Rgb {
  uint8_t r = 255, g = 255, b = 255;
};

struct Point {
  double x = 0, y = 0;
};

class Image {
 public:
  Image(int width, int height, Rgb background = Rgb{});

  int width() const { return width_; }
  int height() const { return height_; }
  Rgb Pixel(int x, int y) const;
  // row-major, 3 bytes per pixel
  const std::vector<uint8_t>& rgb() const { return rgb_; }

  // drawing is clipped to [x0, x1) x [y0, y1) (itself clipped to the image)
  void SetClip(int x0, int y0, int x1, int y1);
  void ResetClip() { SetClip(0, 0, width_, height_); }

  // pixels whose centres lie in [x0, x1) x [y0, y1)
  void FillRect(double x0, double y0, double x1, double y1, Rgb color);

  // an anti-aliased polyline `width` pixels wide; dash > 0 draws dashes and gaps of that length;
  // a non-finite point breaks the line
  void Polyline(const std::vector<Point>& points, Rgb color, double width = 1.5, double dash = 0);
  void Line(double x0, double y0, double x1, double y1, Rgb color, double width = 1.5,
            double dash = 0) {
    Polyline({{x0, y0}, {x1, y1}}, color, width, dash);
  }

  // an anti-aliased filled disk
  void Disk(double cx, double cy, double radius, Rgb color);

  // text in the built-in font; (x, y) is the top left corner of the first character cell
  void Text(int x, int y, const std::string& text, Rgb color, int scale = 1);
  static int TextWidth(const std::string& text, int scale = 1);
  static constexpr int kCellWidth = 6;  // advance at scale 1
  static constexpr int kCapHeight = 7;  // rows above the baseline at scale 1
  static constexpr int kLineHeight = 11;

 private:
  // mixes `color` into pixel (x, y) with weight alpha in [0, 1]; no clipping
  void Blend(int x, int y, Rgb color, double alpha);

  int width_, height_;
  int clip_x0_ = 0, clip_y0_ = 0, clip_x1_ = 0, clip_y1_ = 0;
  std::vector<uint8_t> rgb_;
};

// the bytes of a PNG file holding `image`
std::string EncodePng(const Image& image);

}  // namespace mjsysid::report

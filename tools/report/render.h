// Offscreen rendering of a MuJoCo model with MuJoCo's own renderer (mjv_/mjr_ in libmujoco) in a
// software OpenGL context (OSMesa from Debian's libosmesa6: Mesa's llvmpipe, no GPU, no display),
// loaded at run time (kOsMesaLibrary, dlopen): without it only the renderer is unavailable.
//
// Contract:
// - OffscreenRenderer::Create makes an OSMesa context (RGBA, 24-bit depth, 8-bit stencil,
//   compatibility profile), makes it current on the calling thread, and builds MuJoCo's
//   mjrContext for a private copy of the model (its offscreen buffer at least width x height).
//   mjr_makeContext loads the GL functions itself. When no context can be made (no libOSMesa, or
//   it fails) it returns nullptr and says why: never an error, the caller reports the reason.
// - Render draws the model at one configuration (qpos: nq values; qvel and act zero, mj_forward)
//   from a fixed free camera: at first MuJoCo's default (mjv_defaultFreeCamera: the model's
//   center and extent at qpos0); after Frame, looking at the center of the moving bodies' geoms
//   over the given configurations from far enough that they stay in view. An optional label in the
//   top-left corner (MuJoCo's font), into an RGB image: width*height*3 bytes, row-major, top row
//   first. Equal inputs give equal pixels.
// - One renderer per thread at a time: each call makes its context current on the calling thread.
// - Failure: a MuJoCo error in the renderer is a MujocoError (core/mujoco_env.h); bad shapes are
//   std::invalid_argument.
#pragma once

#include <mujoco/mujoco.h>

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/state.h"

namespace mjsysid::report {

// the library Create loads (Debian's libosmesa6)
inline constexpr char kOsMesaLibrary[] = "libOSMesa.so.8";

// an RGB image: width * height * 3 bytes, top row first
struct RgbImage {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;
};

class OffscreenRenderer {
 public:
  // nullptr when no OpenGL context can be made (*why, if given, says why)
  static std::unique_ptr<OffscreenRenderer> Create(const mjModel& m, int width, int height,
                                                   std::string* why);
  ~OffscreenRenderer();
  OffscreenRenderer(const OffscreenRenderer&) = delete;
  OffscreenRenderer& operator=(const OffscreenRenderer&) = delete;

  int width() const { return width_; }
  int height() const { return height_; }
  // the OpenGL renderer string of the context (e.g. "llvmpipe (LLVM 15.0.6, 256 bits)")
  const std::string& gl_renderer() const { return gl_renderer_; }

  // points the camera at the geoms of the moving bodies (body > 0; planes excepted) over the
  // configurations in the rows of qpos (k x nq): lookat = the center of their bounding box,
  // distance = its half-diagonal / sin(fovy / 2) * 1.1 (the box's sphere fits in the vertical
  // field of view); azimuth and elevation stay MuJoCo's defaults
  void Frame(const Eigen::Ref<const RowMatrix>& qpos);

  // draws the model at qpos (nq) into *out (resized to width x height)
  void Render(const Eigen::Ref<const Eigen::VectorXd>& qpos, const std::string& label,
              RgbImage* out);

 private:
  struct Gl;
  OffscreenRenderer() = default;
  void MakeCurrent();

  int width_ = 0, height_ = 0;
  std::string gl_renderer_;
  std::unique_ptr<Gl> gl_;
  std::vector<uint8_t> flipped_;  // mjr_readPixels' rows, bottom row first
};

}  // namespace mjsysid::report

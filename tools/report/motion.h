// The report's motion section: the initial and the fitted simulation of a fit's first sequence,
// rendered offscreen (tools/report/render.h) side by side, as one looping animated WebP
// (tools/report/encode.h) embedded in the page.
//
// Where the motion comes from: result.yaml names the experiment file; the experiment is loaded
// and its logs mapped to sequences as the fit did (run::BuildProblem), and the sequence is
// re-simulated (core Simulator, one thread) from the log's initial state with the log's controls,
// once at the parameters' initial values and once at the fitted values of result.yaml. The
// controls are held onto the model's steps from their logged times as the fit holds them
// (sysid/data/sample_grid.h): the clip runs on the log's clock at any sample rate (given delays
// applied; a fitted control delay at its start). Where the log has qpos, a third view shows the
// measured motion (the last logged row at or before each frame's time). The fitted
// simulation is the single-shooting rollout of the estimate: with `estimate_initial_state` the
// fit's estimated initial state is not stored in the results, so both clips start from the log's
// state; multiple-shooting segments are not shown.
//
// Clip: the first `max_seconds` of the sequence, one frame every round(1 / (fps * timestep))
// simulation steps; each frame width x height per view, "initial", "fitted" (and "measured"),
// from one fixed free camera that keeps both simulations' moving bodies in view over the whole clip
// (OffscreenRenderer::Frame).
//
// Never an error: when the experiment or its logs cannot be read, a simulation fails, or no
// OpenGL context can be made, the section says so (MotionResult::note) and the report goes on.
#pragma once

#include <functional>
#include <string>

#include "sysid/io/result.h"
#include "tools/report/logged.h"

namespace mjsysid::report {

struct MotionOptions {
  bool enabled = true;  // false: the section says the video was turned off (--no-video)
  int width = 320;      // pixels per view (the frame is 2 or 3 views wide)
  int height = 240;
  double fps = 25;          // target frame rate (the step decimation rounds it)
  double max_seconds = 10;  // at most this much of the sequence
  float quality = 70;       // WebP quality (0..100)
  // progress lines for the terminal (nullptr: none)
  std::function<void(const std::string&)> progress;
};

struct MotionResult {
  std::string note;      // why there is no clip ("" when there is one)
  std::string sequence;  // the sequence shown
  std::string webp;      // the animated WebP (empty without a clip)
  int frames = 0, width = 0, height = 0;
  double seconds = 0;     // simulated time shown
  double fps = 0;         // the frame rate after decimation
  bool measured = false;  // a third view: the log's qpos
  std::string gl_renderer;
};

// renders the clip of result's first sequence (see above), the experiment loaded again
// (LoadLoggedExperiment) or as given
MotionResult MakeMotion(const io::FitResultFile& result, const MotionOptions& options);
MotionResult MakeMotion(const io::FitResultFile& result, const LoggedExperiment& logged,
                        const MotionOptions& options);

// the section: <h2>Motion</h2>, then the clip as <img> (data:image/webp) with a caption, or the
// note
std::string MotionHtml(const MotionResult& motion);

}  // namespace mjsysid::report

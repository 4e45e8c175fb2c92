#include "tools/report/motion.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "core/simulator.h"
#include "sysid/io/experiment.h"
#include "sysid/run/fit_experiment.h"
#include "tools/report/encode.h"
#include "tools/report/page.h"
#include "tools/report/render.h"

namespace mjsysid::report {
namespace {

// a number with `digits` decimals
std::string Fixed(double v, int digits) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.*f", digits, v);
  return buf;
}

void Progress(const MotionOptions& o, const std::string& line) {
  if (o.progress) o.progress(line);
}

// left and right side by side into one frame (2w x h)
void SideBySide(const RgbImage& left, const RgbImage& right, RgbImage* out) {
  const int w = left.width, h = left.height;
  out->width = 2 * w;
  out->height = h;
  out->rgb.resize(static_cast<size_t>(2 * w) * h * 3);
  const size_t row = static_cast<size_t>(w) * 3;
  for (int y = 0; y < h; ++y) {
    std::copy_n(left.rgb.data() + y * row, row, out->rgb.data() + 2 * y * row);
    std::copy_n(right.rgb.data() + y * row, row, out->rgb.data() + (2 * y + 1) * row);
  }
}

}  // namespace

MotionResult MakeMotion(const io::FitResultFile& r, const MotionOptions& o) {
  MotionResult out;
  if (!o.enabled) {
    out.note = "turned off (sysid report --no-video)";
    return out;
  }
  if (r.experiment.empty()) {
    out.note = "the results name no experiment file";
    return out;
  }

  // the experiment, its models and logs, mapped to sequences as the fit did
  run::BuiltProblem built;
  try {
    built = run::BuildProblem(io::LoadExperiment(r.experiment), 1);
  } catch (const std::exception& e) {
    out.note = std::string("the experiment could not be read again: ") + e.what();
    return out;
  }
  const FitSequence* seq = nullptr;
  for (const FitSequence& s : built.sequences) {
    const bool in_result = std::any_of(r.sequences.begin(), r.sequences.end(),
                                       [&](const SequenceResult& q) { return q.name == s.name; });
    if (in_result) {
      seq = &s;
      break;
    }
  }
  if (seq == nullptr) {
    out.note = "none of the experiment's sequences is in the results";
    return out;
  }
  out.sequence = seq->name;
  const auto mi = std::find(built.model_names.begin(), built.model_names.end(), seq->model) -
                  built.model_names.begin();
  const mjModel& m = *built.models.at(mi);

  // the parameters of this model: initial values, and the fitted ones of the results by name
  std::map<std::string, double> fitted;
  for (const ParameterEstimate& p : r.parameters) fitted[p.name] = p.value;
  std::vector<ParameterSpec> specs;
  Eigen::VectorXd initial, final_values;
  std::vector<double> init_v, final_v;
  for (const FitParameter& p : built.parameters) {
    if (!p.AppliesTo(seq->model)) continue;
    ParameterSpec spec = p.target;
    spec.label = p.name;
    specs.push_back(spec);
    init_v.push_back(p.initial);
    const auto it = fitted.find(p.name);
    final_v.push_back(it != fitted.end() ? it->second : p.initial);
  }
  initial = Eigen::Map<Eigen::VectorXd>(init_v.data(), init_v.size());
  final_values = Eigen::Map<Eigen::VectorXd>(final_v.data(), final_v.size());

  // the first max_seconds of the sequence, at the initial and at the fitted values
  const double dt = m.opt.timestep;
  const int T = static_cast<int>(seq->ctrl.rows());
  const int steps = std::max(1, std::min(T, static_cast<int>(std::floor(o.max_seconds / dt))));
  const int stride = std::max(1, static_cast<int>(std::lround(1.0 / (o.fps * dt))));
  SequenceInput input{seq->x0, seq->ctrl.topRows(steps)};
  Trajectory initial_run, fitted_run;
  try {
    Simulator sim(m, specs);
    sim.SetParameters(initial);
    initial_run = sim.Rollout(input);
    sim.SetParameters(final_values);
    fitted_run = sim.Rollout(input);
  } catch (const std::exception& e) {
    out.note = "sequence " + seq->name + " could not be simulated: " + e.what();
    return out;
  }

  // one frame every `stride` steps: x_0, x_stride, ... up to x_steps
  std::string why;
  std::unique_ptr<OffscreenRenderer> renderer =
      OffscreenRenderer::Create(m, o.width, o.height, &why);
  if (!renderer) {
    out.note = "no OpenGL available for rendering (" + why + ")";
    return out;
  }
  out.gl_renderer = renderer->gl_renderer();
  const int frames = steps / stride + 1;
  // the camera frames both simulations over the whole clip
  RowMatrix shown(2 * frames, m.nq);
  for (int f = 0; f < frames; ++f) {
    shown.row(2 * f) = initial_run.states.row(f * stride).head(m.nq);
    shown.row(2 * f + 1) = fitted_run.states.row(f * stride).head(m.nq);
  }
  Progress(o, "rendering motion of sequence " + seq->name + ": " + std::to_string(frames) +
                  " frames, initial and fitted, " + std::to_string(o.width) + "x" +
                  std::to_string(o.height) + " each (" + out.gl_renderer + ")");
  std::vector<RgbImage> video(frames);
  RgbImage left, right;
  const int nq = m.nq;
  try {
    renderer->Frame(shown);
    for (int f = 0; f < frames; ++f) {
      const int k = f * stride;
      renderer->Render(initial_run.states.row(k).head(nq).transpose(), "initial", &left);
      renderer->Render(fitted_run.states.row(k).head(nq).transpose(), "fitted", &right);
      SideBySide(left, right, &video[f]);
    }
  } catch (const std::exception& e) {
    out.note = std::string("rendering failed: ") + e.what();
    return out;
  }
  const int frame_ms = static_cast<int>(std::lround(1000 * stride * dt));
  out.webp = EncodeAnimatedWebp(video, std::max(frame_ms, 1), o.quality);
  out.frames = frames;
  out.width = 2 * o.width;
  out.height = o.height;
  out.seconds = steps * dt;
  out.fps = 1 / (stride * dt);
  return out;
}

std::string MotionHtml(const MotionResult& motion) {
  std::ostringstream h;
  h << "<h2>Motion</h2>\n";
  if (motion.webp.empty()) {
    h << "<p class=\"muted\">no video: " << HtmlEscape(motion.note) << "</p>\n";
    return h.str();
  }
  h << "<h3>" << HtmlEscape(motion.sequence) << "</h3>\n<img class=\"motion\" alt=\"motion "
    << HtmlEscape(motion.sequence) << "\" width=\"" << motion.width << "\" height=\""
    << motion.height << "\" src=\"data:image/webp;base64," << Base64(motion.webp) << "\">\n"
    << "<p class=\"muted\">left: simulated with the initial parameter values; right: with the "
       "fitted ones; both from the log's initial state with the log's controls. "
    << Fixed(motion.seconds, 2) << " s simulated, " << motion.frames << " frames at "
    << Fixed(motion.fps, 1) << " fps, looping (" << Fixed(motion.webp.size() / 1024.0, 0)
    << " KiB animated WebP)</p>\n";
  return h.str();
}

}  // namespace mjsysid::report

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
#include "sysid/data/sample_grid.h"
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

// the views (each w x h) side by side into one frame (n w x h)
void SideBySide(const std::vector<RgbImage>& views, RgbImage* out) {
  const int w = views[0].width, h = views[0].height;
  const size_t n = views.size();
  out->width = static_cast<int>(n) * w;
  out->height = h;
  out->rgb.resize(n * static_cast<size_t>(w) * h * 3);
  const size_t row = static_cast<size_t>(w) * 3;
  for (int y = 0; y < h; ++y) {
    for (size_t v = 0; v < n; ++v) {
      std::copy_n(views[v].rgb.data() + y * row, row, out->rgb.data() + (n * y + v) * row);
    }
  }
}

// the row of the logged qpos in force at time t (the last measured row at or before it: a log's
// own samples, never interpolated, so that a quaternion stays one); -1 before the first
Eigen::Index LoggedRowAt(const FitSequence& seq, double t) {
  Eigen::Index row = -1;
  for (Eigen::Index k = 0; k < seq.qpos.rows() && seq.time[k] <= t + 1e-9; ++k) {
    if (!seq.qpos.row(k).array().isNaN().any()) row = k;
  }
  return row;
}

}  // namespace

MotionResult MakeMotion(const io::FitResultFile& r, const MotionOptions& o) {
  if (!o.enabled) return MakeMotion(r, LoggedExperiment(), o);  // says it was turned off
  return MakeMotion(r, LoadLoggedExperiment(r), o);
}

MotionResult MakeMotion(const io::FitResultFile& r, const LoggedExperiment& logged,
                        const MotionOptions& o) {
  MotionResult out;
  if (!o.enabled) {
    out.note = "turned off (sysid report --no-video)";
    return out;
  }
  if (!logged.note.empty()) {
    out.note = logged.note;
    return out;
  }

  // the first of the result's sequences that the experiment has, mapped as the fit did
  const run::BuiltProblem& built = logged.built;
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
  const mjModel* model = logged.ModelOf(*seq);
  if (model == nullptr) {
    out.note = "sequence " + seq->name + ": its model " + seq->model + " is not in the experiment";
    return out;
  }
  const mjModel& m = *model;

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

  // the first max_seconds of the sequence on the log's clock: the controls of each simulation
  // step held from the logged ones at their own times (sysid/data/sample_grid.h, as the fit
  // holds them; given delays applied, fitted ones at their starts), at the initial and at the
  // fitted values
  const double dt = m.opt.timestep;
  SampleGrid grid;
  try {
    grid = BuildSampleGrid(seq->time, static_cast<int>(seq->measured.rows()), seq->x0.time,
                           seq->ctrl, seq->ctrl_time, seq->ctrl_hold, seq->ctrl_delay, dt,
                           "sequence " + seq->name + ": ", seq->ctrl_before);
  } catch (const std::exception& e) {
    out.note = "sequence " + seq->name + ": its controls could not be placed on the model's " +
               "steps: " + e.what();
    return out;
  }
  const int steps =
      std::max(1, std::min(grid.steps, static_cast<int>(std::floor(o.max_seconds / dt))));
  const int stride = std::max(1, static_cast<int>(std::lround(1.0 / (o.fps * dt))));
  SequenceInput input{seq->x0, grid.ctrl.topRows(steps)};
  const double t0 = seq->time.size() ? seq->time[0] : seq->x0.time;
  // the measured motion beside them where the log has qpos (and times to place it)
  const bool measured =
      seq->qpos.rows() > 0 && seq->qpos.cols() == m.nq && seq->time.size() == seq->qpos.rows();
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
  const int nq = m.nq;
  // each frame's logged qpos (frame f at t0 + f stride dt; before the first measured row, the
  // fitted simulation's, which starts from the log's state)
  RowMatrix logged_qpos(measured ? frames : 0, nq);
  for (int f = 0; f < logged_qpos.rows(); ++f) {
    const Eigen::Index row = LoggedRowAt(*seq, t0 + f * stride * dt);
    if (row >= 0) {
      logged_qpos.row(f) = seq->qpos.row(row);
    } else {
      logged_qpos.row(f) = fitted_run.states.row(f * stride).head(nq);
    }
  }
  const int views = measured ? 3 : 2;
  // the camera frames every view over the whole clip
  RowMatrix shown(views * frames, nq);
  for (int f = 0; f < frames; ++f) {
    shown.row(views * f) = initial_run.states.row(f * stride).head(nq);
    shown.row(views * f + 1) = fitted_run.states.row(f * stride).head(nq);
    if (measured) shown.row(views * f + 2) = logged_qpos.row(f);
  }
  Progress(o, "rendering motion of sequence " + seq->name + ": " + std::to_string(frames) +
                  " frames, initial and fitted" + (measured ? " and measured, " : ", ") +
                  std::to_string(o.width) + "x" + std::to_string(o.height) + " each (" +
                  out.gl_renderer + ")");
  std::vector<RgbImage> video(frames);
  std::vector<RgbImage> view(views);
  try {
    renderer->Frame(shown);
    for (int f = 0; f < frames; ++f) {
      const int k = f * stride;
      renderer->Render(initial_run.states.row(k).head(nq).transpose(), "initial", &view[0]);
      renderer->Render(fitted_run.states.row(k).head(nq).transpose(), "fitted", &view[1]);
      if (measured) renderer->Render(logged_qpos.row(f).transpose(), "measured", &view[2]);
      SideBySide(view, &video[f]);
    }
  } catch (const std::exception& e) {
    out.note = std::string("rendering failed: ") + e.what();
    return out;
  }
  const int frame_ms = static_cast<int>(std::lround(1000 * stride * dt));
  out.webp = EncodeAnimatedWebp(video, std::max(frame_ms, 1), o.quality);
  out.frames = frames;
  out.width = views * o.width;
  out.height = o.height;
  out.measured = measured;
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
    << "<p class=\"muted\">left: simulated with the initial parameter values; middle"
    << (motion.measured ? "" : " (right)")
    << ": with the fitted ones; both from the log's initial state with the log's controls on "
       "the log's clock"
    << (motion.measured ? "; right: the measured motion (the log's qpos)" : "") << ". "
    << Fixed(motion.seconds, 2) << " s simulated, " << motion.frames << " frames at "
    << Fixed(motion.fps, 1) << " fps, looping (" << Fixed(motion.webp.size() / 1024.0, 0)
    << " KiB animated WebP)</p>\n";
  return h.str();
}

}  // namespace mjsysid::report

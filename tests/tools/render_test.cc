// The report's motion pieces with real parts: MuJoCo's renderer in a real OSMesa context
// (tools/report/render.h), real libwebp encoding and decoding (tools/report/encode.h), and the
// motion section's notes (tools/report/motion.h). OSMesa is required: without it the render tests
// fail (tools/bootstrap.sh installs libosmesa6).
#include "tools/report/render.h"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "sysid/io/log.h"
#include "tests/experiment_log.h"
#include "tests/file_util.h"
#include "tools/report/encode.h"
#include "tools/report/motion.h"

namespace mjsysid::report {
namespace {

ModelPtr Pendulum() { return LoadModel(std::string(MJSYSID_MODELS_DIR) + "/pendulum.xml"); }

// pixels whose RGB differs from the top-left corner's by more than 30 in some channel (not
// background)
int Foreground(const RgbImage& im) {
  int n = 0;
  for (size_t i = 0; i < im.rgb.size(); i += 3) {
    for (int c = 0; c < 3; ++c) {
      if (std::abs(im.rgb[i + c] - im.rgb[c]) > 30) {
        ++n;
        break;
      }
    }
  }
  return n;
}

// pixels that differ by more than 30 in some channel between two images of one size
int Changed(const RgbImage& a, const RgbImage& b) {
  int n = 0;
  for (size_t i = 0; i < a.rgb.size(); i += 3) {
    for (int c = 0; c < 3; ++c) {
      if (std::abs(a.rgb[i + c] - b.rgb[i + c]) > 30) {
        ++n;
        break;
      }
    }
  }
  return n;
}

std::unique_ptr<OffscreenRenderer> Renderer(const mjModel& m, int w, int h) {
  std::string why;
  auto r = OffscreenRenderer::Create(m, w, h, &why);
  EXPECT_NE(r, nullptr) << "no offscreen OpenGL context: " << why;
  return r;
}

TEST(RenderTest, PendulumFramesAreNonblankDifferAndRepeat) {
  ModelPtr m = Pendulum();
  auto r = Renderer(*m, 320, 240);
  ASSERT_NE(r, nullptr);
  EXPECT_FALSE(r->gl_renderer().empty());
  Eigen::VectorXd q0(1), q1(1);
  q0 << 0.0;
  q1 << 1.2;  // rad: the bob ~0.47 m to the side
  RowMatrix both(2, 1);
  both << q0, q1;
  r->Frame(both);
  RgbImage a, b, a2;
  r->Render(q0, "", &a);
  r->Render(q1, "", &b);
  r->Render(q0, "", &a2);
  // the size asked for, exactly
  EXPECT_EQ(a.width, 320);
  EXPECT_EQ(a.height, 240);
  ASSERT_EQ(a.rgb.size(), 320u * 240 * 3);
  // the rod and the bob: a few hundred pixels of the 76800 (measured 525 hanging, 774 at 1.2 rad)
  EXPECT_GT(Foreground(a), 200);
  EXPECT_LT(Foreground(a), 320 * 240 / 4);
  // another angle moves them
  EXPECT_GT(Changed(a, b), 200);  // measured 1214
  // the same state gives the same pixels
  EXPECT_EQ(a.rgb, a2.rgb);
}

TEST(RenderTest, FrameKeepsTheMotionInView) {
  // the pendulum swung to +-1.5 rad (the bob ~0.5 m to either side): after Frame no drawn pixel
  // touches the image border, and the swing spans more of the width than with MuJoCo's default
  // camera
  ModelPtr m = Pendulum();
  auto r = Renderer(*m, 320, 240);
  ASSERT_NE(r, nullptr);
  RowMatrix swing(3, 1);
  swing << -1.5, 0.0, 1.5;
  auto span = [&](int* touching) {
    int x_lo = 320, x_hi = -1;
    *touching = 0;
    for (int k = 0; k < 3; ++k) {
      RgbImage im;
      r->Render(swing.row(k).transpose(), "", &im);
      for (int y = 0; y < 240; ++y) {
        for (int x = 0; x < 320; ++x) {
          const size_t i = (static_cast<size_t>(y) * 320 + x) * 3;
          if (std::abs(im.rgb[i] - im.rgb[0]) <= 30) continue;
          x_lo = std::min(x_lo, x);
          x_hi = std::max(x_hi, x);
          *touching += x == 0 || y == 0 || x == 319 || y == 239;
        }
      }
    }
    return x_hi - x_lo;
  };
  int touching = 0;
  const int default_span = span(&touching);
  r->Frame(swing);
  const int framed_span = span(&touching);
  EXPECT_EQ(touching, 0);
  EXPECT_GT(framed_span, default_span);  // measured 157 vs 125 pixels
  EXPECT_THROW(r->Frame(RowMatrix::Zero(2, 3)), std::invalid_argument);
}

TEST(RenderTest, TheLabelIsDrawn) {
  ModelPtr m = Pendulum();
  auto r = Renderer(*m, 320, 240);
  ASSERT_NE(r, nullptr);
  Eigen::VectorXd q(1);
  q << 0.3;
  RgbImage plain, labelled;
  r->Render(q, "", &plain);
  r->Render(q, "fitted", &labelled);
  // the text in the top-left quarter only
  int top_left = 0, elsewhere = 0;
  for (int y = 0; y < 240; ++y) {
    for (int x = 0; x < 320; ++x) {
      const size_t i = (static_cast<size_t>(y) * 320 + x) * 3;
      if (plain.rgb[i] == labelled.rgb[i] && plain.rgb[i + 1] == labelled.rgb[i + 1] &&
          plain.rgb[i + 2] == labelled.rgb[i + 2]) {
        continue;
      }
      (x < 160 && y < 60 ? top_left : elsewhere)++;
    }
  }
  EXPECT_GT(top_left, 50);
  EXPECT_EQ(elsewhere, 0);
}

TEST(RenderTest, BadShapesAreRefused) {
  ModelPtr m = Pendulum();
  std::string why;
  EXPECT_THROW(OffscreenRenderer::Create(*m, 0, 240, &why), std::invalid_argument);
  auto r = Renderer(*m, 64, 48);
  ASSERT_NE(r, nullptr);
  RgbImage out;
  EXPECT_THROW(r->Render(Eigen::VectorXd::Zero(2), "", &out), std::invalid_argument);
}

TEST(EncodeTest, AnimatedWebpRoundTrip) {
  // six frames of the pendulum swinging, 40 ms each
  ModelPtr m = Pendulum();
  auto r = Renderer(*m, 160, 120);
  ASSERT_NE(r, nullptr);
  std::vector<RgbImage> frames(6);
  for (int f = 0; f < 6; ++f) {
    Eigen::VectorXd q(1);
    q << -0.9 + 0.35 * f;
    r->Render(q, "initial", &frames[f]);
  }
  const std::string webp = EncodeAnimatedWebp(frames, 40);
  ASSERT_GT(webp.size(), 12u);
  EXPECT_EQ(webp.substr(0, 4), "RIFF");
  EXPECT_EQ(webp.substr(8, 4), "WEBP");

  // decoded with the same library: count, size, timing, loop, and the pixels (lossy at quality
  // 70: a mean absolute error below 1 of 255 per channel, measured 0.23-0.25)
  const DecodedAnimation back = DecodeAnimatedWebp(webp);
  EXPECT_EQ(back.width, 160);
  EXPECT_EQ(back.height, 120);
  EXPECT_EQ(back.loop_count, 0);
  ASSERT_EQ(back.frames.size(), 6u);
  for (int f = 0; f < 6; ++f) {
    EXPECT_EQ(back.end_ms[f], 40 * (f + 1));
    double error = 0;
    for (size_t i = 0; i < frames[f].rgb.size(); ++i) {
      error += std::abs(back.frames[f].rgb[i] - frames[f].rgb[i]);
    }
    EXPECT_LT(error / frames[f].rgb.size(), 1.0) << "frame " << f;
  }
  EXPECT_GT(Changed(back.frames[0], back.frames[5]), 100);
}

TEST(EncodeTest, BadInputIsRefused) {
  EXPECT_THROW(EncodeAnimatedWebp({}, 40), std::invalid_argument);
  RgbImage a{4, 4, std::vector<uint8_t>(4 * 4 * 3, 0)}, b{4, 3, std::vector<uint8_t>(4 * 3 * 3)};
  EXPECT_THROW(EncodeAnimatedWebp({a, b}, 40), std::invalid_argument);
  EXPECT_THROW(DecodeAnimatedWebp("RIFF0000WEBPnot really"), std::runtime_error);
}

TEST(MotionTest, NoClipSaysWhy) {
  io::FitResultFile r;
  MotionOptions off;
  off.enabled = false;
  MotionResult motion = MakeMotion(r, off);
  EXPECT_TRUE(motion.webp.empty());
  EXPECT_NE(motion.note.find("--no-video"), std::string::npos) << motion.note;
  EXPECT_NE(MotionHtml(motion).find("<h2>Motion</h2>"), std::string::npos);
  EXPECT_NE(MotionHtml(motion).find("no video: turned off"), std::string::npos);

  // an experiment file that is gone: a note naming it, no error
  r.experiment = "/nonexistent/pendulum.yaml";
  motion = MakeMotion(r, MotionOptions());
  EXPECT_TRUE(motion.webp.empty());
  EXPECT_NE(motion.note.find("could not be read again"), std::string::npos) << motion.note;
  EXPECT_NE(motion.note.find("/nonexistent/pendulum.yaml"), std::string::npos) << motion.note;
}

// The clip on the log's clock with the measured motion: the shipped pendulum experiment's log
// (1 sequence of 2000 steps at 2 ms, with qpos) kept at every 5th row (a 100 Hz log of the 2 ms
// model, 3.99 s). The clip shows the 3.99 s the log spans (it showed 400 rows as 400 steps,
// 0.8 s, with the commands 5x too fast), and a third view, the log's qpos
TEST(MotionTest, TheClipFollowsTheLogsClockAndShowsTheMeasuredMotion) {
  const std::string dir = test::FreshTempDir("motion_clock");
  io::ExperimentConfig cfg = test::ShippedExperimentWithLog("pendulum.yaml", 1, 2000, "motion_log");
  io::Log log = io::ReadLog(cfg.data[0].path);
  io::Sequence& s = log.sequences[0];
  std::vector<int> keep;
  for (int k = 0; k < s.time.size(); k += 5) keep.push_back(k);
  auto rows = [&](const RowMatrix& m) {
    RowMatrix out(static_cast<Eigen::Index>(keep.size()), m.cols());
    for (size_t i = 0; i < keep.size(); ++i) out.row(i) = m.row(keep[i]);
    return out;
  };
  Eigen::VectorXd time(static_cast<Eigen::Index>(keep.size()));
  for (size_t i = 0; i < keep.size(); ++i) time[i] = s.time[keep[i]];
  s.time = time;
  s.ctrl = rows(s.ctrl);
  s.sensordata = rows(s.sensordata);
  s.qpos = rows(s.qpos);
  s.qvel = rows(s.qvel);
  io::WriteLog(dir + "/log.h5", log);
  // the experiment on that log, its model path absolute
  std::string text = test::ReadFile(std::string(MJSYSID_EXPERIMENTS_DIR) + "/pendulum.yaml");
  text.replace(text.find("model: ../models/"), 17,
               "model: " + std::string(MJSYSID_MODELS_DIR) + "/");
  text.replace(text.find("data: logs/pendulum.h5"), 22, "data: " + dir + "/log.h5");
  std::ofstream(dir + "/exp.yaml") << text;
  io::FitResultFile r;
  r.experiment = dir + "/exp.yaml";
  r.sequences.resize(1);
  r.sequences[0].name = s.name;
  const MotionResult motion = MakeMotion(r, MotionOptions());
  ASSERT_FALSE(motion.webp.empty()) << motion.note;
  std::printf("[ measured ] clip of a %.3f s log at 100 Hz: %.3f s, %d frames, %dx%d\n",
              time[time.size() - 1] - time[0], motion.seconds, motion.frames, motion.width,
              motion.height);
  EXPECT_NEAR(motion.seconds, time[time.size() - 1] - time[0], 0.01);
  EXPECT_TRUE(motion.measured);
  EXPECT_EQ(motion.width, 3 * MotionOptions().width);
  EXPECT_NE(MotionHtml(motion).find("right: the measured motion"), std::string::npos);
  const DecodedAnimation clip = DecodeAnimatedWebp(motion.webp);
  EXPECT_EQ(static_cast<int>(clip.frames.size()), motion.frames);
  EXPECT_EQ(clip.width, motion.width);
  // the clip plays in the log's time: its last frame ends about 4 s in
  ASSERT_FALSE(clip.end_ms.empty());
  EXPECT_NEAR(clip.end_ms.back(), 1000 * motion.seconds, 100);
}

}  // namespace
}  // namespace mjsysid::report

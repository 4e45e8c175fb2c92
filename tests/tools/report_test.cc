#include "tools/report/report.h"

#include <cairo.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <iterator>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "sysid/assess/residual_diagnostics.h"
#include "tests/file_util.h"
#include "tests/temp_dir_test.h"
#include "tests/tools/png_util.h"
#include "tools/report/axes.h"
#include "tools/report/canvas.h"
#include "tools/report/correlation.h"
#include "tools/report/interactive.h"
#include "tools/report/logged.h"
#include "tools/report/page.h"

namespace mjsysid::report {
namespace {

namespace fs = std::filesystem;
constexpr double kInf = std::numeric_limits<double>::infinity();

// ---------------------------------------------------------------------------------------------
// helpers

// a fresh directory per test (test::TempDirTest)
class ReportTest : public test::TempDirTest {
 protected:
};

using test::ReadFile;

// a damped oscillation with a given frequency and damping
double Swing(double t, double freq, double damping) {
  return std::exp(-damping * t) * std::sin(2 * M_PI * freq * t);
}

// two parameters (one unidentifiable), a short trace, one sequence with two sensor columns
io::FitResultFile Result(Eigen::Index samples = 600) {
  io::FitResultFile r;
  r.name = "pendulum";
  r.experiment = "experiments/pendulum.yaml";
  r.status = "converged";
  r.termination.kind = FitTermination::Kind::kSolverConvergence;
  r.termination.solver_message = "function tolerance reached";
  r.created = "2024-05-01T12:00:00Z";
  r.mjsysid_version = "0.1.0";
  r.mujoco_version = "4.0.0";
  r.diagnostics.jacobian_mode = "analytic";
  r.iterations = 6;
  r.num_residuals = static_cast<int>(2 * samples);
  r.initial_cost = 12.5;
  r.final_cost = 0.0031;
  r.uncertainty.residual_variance = 2.6e-6;
  r.seconds = 1.75;
  r.solver = {{"max_iterations", "100"}, {"function_tolerance", "1e-10"}};

  ParameterEstimate damping;
  damping.name = "damping";
  damping.initial = 0.2;
  damping.value = 0.0803;
  damping.std_error = 0.0011;
  damping.ci95_low = damping.value - 1.96 * damping.std_error;
  damping.ci95_high = damping.value + 1.96 * damping.std_error;
  damping.truth = 0.08;
  ParameterEstimate mass;
  mass.name = "bob_mass";
  mass.initial = 1.0;
  mass.value = 1.37;
  mass.std_error = kInf;
  mass.ci95_low = -kInf;
  mass.ci95_high = kInf;
  mass.identifiable = false;
  mass.truth = 1.2;
  r.parameters = {damping, mass};
  r.uncertainty.unidentifiable = {"bob_mass (no sensor sees the mass: singular value 3e-15)"};
  r.warnings = {"sequence seq0: sensor 'rate' saturates at 10 rad/s <check>"};

  // cost and parameters converging over the iterations; one rejected step
  for (int i = 0; i <= 6; ++i) {
    IterationInfo e;
    e.iteration = i;
    e.cost = 12.5 * std::pow(0.25, i * i / 2.0) + 0.0031;
    e.step_norm = 0.5 / (i + 1);
    e.gradient_norm = std::exp(-2.0 * i);
    e.seconds = 0.25 * (i + 1);
    e.successful = i != 3;
    e.parameters =
        Eigen::Vector2d(0.08 + 0.12 * std::exp(-1.2 * i), 1.0 + 0.37 * (1 - std::exp(-0.8 * i)));
    r.trace.push_back(e);
  }

  // a swinging pendulum: angle and rate, before and after the fit
  SequenceResult s;
  s.name = "seq0";
  s.model = "pendulum";
  s.sensor_names = {"angle", "rate"};
  s.sensor_dims = {1, 1};
  s.time.resize(samples);
  s.measured.resize(samples, 2);
  s.simulated_initial.resize(samples, 2);
  s.simulated_final.resize(samples, 2);
  for (Eigen::Index k = 0; k < samples; ++k) {
    const double t = 0.01 * static_cast<double>(k);
    s.time[k] = t;
    const double noise = 0.02 * std::sin(37.0 * k) * std::cos(11.0 * k);
    s.measured(k, 0) = Swing(t, 0.8, 0.3) + noise;
    s.measured(k, 1) = 5.0 * Swing(t + 0.3, 0.8, 0.3) + 5 * noise;
    s.simulated_initial(k, 0) = 1.2 * Swing(t, 0.7, 0.8);
    s.simulated_initial(k, 1) = 6.0 * Swing(t + 0.3, 0.7, 0.8);
    s.simulated_final(k, 0) = Swing(t, 0.8, 0.3);
    s.simulated_final(k, 1) = 5.0 * Swing(t + 0.3, 0.8, 0.3);
  }
  r.sequences = {s};
  r.uncertainty.covariance = Eigen::MatrixXd::Identity(2, 2);
  r.uncertainty.covariance(1, 1) = kInf;
  return r;
}

// a decoded png: its size and the rgb pixels, row-major
struct Png {
  uint32_t width = 0, height = 0;
  std::vector<uint8_t> rgb;
  Rgb Pixel(uint32_t x, uint32_t y) const {
    const size_t i = (static_cast<size_t>(y) * width + x) * 3;
    return Rgb{rgb[i], rgb[i + 1], rgb[i + 2]};
  }
};

// decodes with cairo (libpng: signature, chunk CRCs, zlib stream); the header must say 8-bit RGB
::testing::AssertionResult Decode(const std::string& bytes, Png* out) {
  if (bytes.size() < 26 || bytes.compare(12, 4, "IHDR") != 0) {
    return ::testing::AssertionFailure() << "no png header";
  }
  if (bytes[24] != 8 || bytes[25] != 2) return ::testing::AssertionFailure() << "not 8-bit rgb";
  cairo_surface_t* s = test::SurfaceFromPng(bytes);
  const cairo_status_t status = cairo_surface_status(s);
  if (status != CAIRO_STATUS_SUCCESS) {
    cairo_surface_destroy(s);
    return ::testing::AssertionFailure() << "cairo: " << cairo_status_to_string(status);
  }
  // pixels as native-endian 32-bit words 0xXXRRGGBB
  out->width = static_cast<uint32_t>(cairo_image_surface_get_width(s));
  out->height = static_cast<uint32_t>(cairo_image_surface_get_height(s));
  const int stride = cairo_image_surface_get_stride(s);
  const unsigned char* data = cairo_image_surface_get_data(s);
  out->rgb.clear();
  for (uint32_t y = 0; y < out->height; ++y) {
    const auto* row = reinterpret_cast<const uint32_t*>(data + static_cast<size_t>(y) * stride);
    for (uint32_t x = 0; x < out->width; ++x) {
      out->rgb.push_back(static_cast<uint8_t>(row[x] >> 16));
      out->rgb.push_back(static_cast<uint8_t>(row[x] >> 8));
      out->rgb.push_back(static_cast<uint8_t>(row[x]));
    }
  }
  const bool rgb24 = cairo_image_surface_get_format(s) == CAIRO_FORMAT_RGB24;
  cairo_surface_destroy(s);
  if (!rgb24) return ::testing::AssertionFailure() << "decoded with an alpha channel";
  return ::testing::AssertionSuccess();
}

// grey-or-white and coloured pixels counted
struct Colors {
  size_t grey = 0, colored = 0;
};
Colors CountColors(const Png& png) {
  Colors c;
  for (size_t i = 0; i + 2 < png.rgb.size(); i += 3) {
    const int r = png.rgb[i], g = png.rgb[i + 1], b = png.rgb[i + 2];
    const int spread = std::max({r, g, b}) - std::min({r, g, b});
    if (spread == 0) ++c.grey;
    if (spread > 80) ++c.colored;
  }
  return c;
}

// a plot of this size, mostly white or grey, with coloured lines; at least 50 pixels of exactly
// each of `curves` (the solid middle of a line or marker drawn in that colour)
void ExpectPlot(const std::string& path, uint32_t width, uint32_t height,
                const std::vector<Rgb>& curves = {}) {
  SCOPED_TRACE(path);
  Png png;
  ASSERT_TRUE(Decode(ReadFile(path), &png));
  EXPECT_EQ(png.width, width);
  EXPECT_EQ(png.height, height);
  const Colors c = CountColors(png);
  EXPECT_GT(c.grey, png.rgb.size() / 6) << "background";
  EXPECT_GT(c.colored, 500u) << "lines";
  for (const Rgb& want : curves) {
    size_t n = 0;
    for (size_t i = 0; i + 2 < png.rgb.size(); i += 3) {
      n += png.rgb[i] == want.r && png.rgb[i + 1] == want.g && png.rgb[i + 2] == want.b;
    }
    EXPECT_GE(n, 50u) << "colour " << int(want.r) << "," << int(want.g) << "," << int(want.b);
  }
}

// ---------------------------------------------------------------------------------------------
// the report

TEST_F(ReportTest, WritesAPageAndPlotsFromTheResultFiles) {
  const io::FitResultFile r = Result();
  io::WriteResultYaml(Path("result.yaml"), r);
  io::WriteResultH5(Path("result.h5"), r);
  std::string summary;
  EXPECT_EQ(WriteReport(Dir(), &summary), 4);

  // the page: self-contained, with the parameters and the identifiability finding
  const std::string html = ReadFile(Path("report.html"));
  ASSERT_FALSE(html.empty());
  for (const char* needle : {"<!DOCTYPE html>", "pendulum", "damping", "bob_mass", "unidentifiable",
                             "converged", "function tolerance reached", "max_iterations", "4.0.0",
                             "no sensor sees the mass", "saturates at 10 rad/s &lt;check&gt;",
                             "<svg", "data:image/png;base64,", "class=\"unid\""}) {
    EXPECT_NE(html.find(needle), std::string::npos) << needle;
  }
  // nothing loaded from elsewhere (the inlined library's licence comment names its URL)
  for (const char* banned : {"src=\"http", "href=\"http", "url(http", "url(//", "<script src",
                             "<link", "@import", "sourceMappingURL"}) {
    EXPECT_EQ(html.find(banned), std::string::npos) << banned;
  }

  // the plots: sizes follow the layout (cost 900 x 440; parameter panels 400 x 260 under a
  // 44 px legend, 3 per row; sequence panels 1200 x 230 under a 76 px header)
  ExpectPlot(Path("cost.png"), 900, 440, {kBefore, kAlert});
  ExpectPlot(Path("parameters.png"), 800, 44 + 260, {kBefore, kAfter, kTruth, kUnidentifiable});
  ExpectPlot(Path("seq_seq0.png"), 1200, 76 + 2 * 230, {kMeasured, kBefore, kAfter});

  // the summary names the files; nothing else is left behind
  EXPECT_NE(summary.find("report pendulum"), std::string::npos) << summary;
  EXPECT_NE(summary.find("1 unidentifiable: bob_mass"), std::string::npos) << summary;
  EXPECT_NE(summary.find("seq_seq0.png"), std::string::npos) << summary;
  size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir_)) {
    EXPECT_EQ(e.path().string().find(".tmp-"), std::string::npos) << e.path();
    ++files;
  }
  EXPECT_EQ(files, 6u);
}

TEST_F(ReportTest, LongSequencesAreDecimatedAndManyColumnsTiled) {
  io::FitResultFile r = Result(200000);
  r.trace.clear();  // no trace: first and last values only
  SequenceResult& s = r.sequences[0];
  s.name = "long run/1";
  // a one-sample spike survives decimation: it sets the y range of the angle panel
  s.measured(123457, 0) = 40;
  // 6 columns: two per row
  s.sensor_names = {"angle", "rate", "acc"};
  s.sensor_dims = {1, 1, 4};
  for (RowMatrix* m : {&s.measured, &s.simulated_initial, &s.simulated_final}) {
    m->conservativeResize(Eigen::NoChange, 6);
    for (Eigen::Index j = 2; j < 6; ++j) m->col(j) = m->col(j % 2) * static_cast<double>(j);
  }
  EXPECT_EQ(WriteReport(r, Dir(), nullptr), 4);
  ExpectPlot(Path("seq_long_run_1.png"), 1200, 76 + 3 * 230);
  ExpectPlot(Path("cost.png"), 900, 440);
  EXPECT_LT(fs::file_size(Path("report.html")), 3u << 20);
}

// the derived quantities (body_inertial: mass, com, principal moments) get their own table
// below the parameters, with unit, interval and where they come from; a result without any has none
TEST_F(ReportTest, DerivedQuantitiesGetATable) {
  io::FitResultFile r = Result(50);
  EXPECT_EQ(WriteReport(r, Dir(), nullptr), 4);
  EXPECT_EQ(ReadFile(Path("report.html")).find("Derived quantities"), std::string::npos);
  DerivedQuantity d;
  d.name = "link7.mass";
  d.unit = "kg";
  d.value = 1.25;
  d.std_error = 0.01;
  d.ci95_low = 1.23;
  d.ci95_high = 1.27;
  d.derived_from = "body_inertial (payload_alpha) by the delta method";
  r.derived.push_back(d);
  EXPECT_EQ(WriteReport(r, Dir(), nullptr), 4);
  const std::string html = ReadFile(Path("report.html"));
  const size_t table = html.find("<h3>Derived quantities</h3>");
  ASSERT_NE(table, std::string::npos);
  EXPECT_LT(html.find("<h2>Parameters</h2>"), table);
  EXPECT_NE(html.find("<td>link7.mass</td><td>kg</td>", table), std::string::npos);
  EXPECT_NE(html.find("body_inertial (payload_alpha) by the delta method", table),
            std::string::npos);
}

// how often `needle` occurs in `text`
size_t Count(const std::string& text, const std::string& needle) {
  size_t n = 0;
  for (size_t at = text.find(needle); at != std::string::npos; at = text.find(needle, at + 1)) ++n;
  return n;
}

// The page's interactive views: per sensor column a signal chart and a residual chart (its
// diagnostics in the caption, +-2 sigma shaded), the residuals' autocorrelation per channel, the
// library inlined once, the still plot folded below; no inputs without the experiment's logs.
TEST_F(ReportTest, ThePageHasInteractiveChartsForSignalsResidualsAndTheirAutocorrelation) {
  io::FitResultFile r = Result();
  // the diagnostics as the fit makes them, with a sigma for the angle (0.02) and none for the rate
  FitOptions o;
  o.sensors_with_sigma = {"angle"};
  o.sensor_weights["angle"] = 1 / 0.02;
  r.residuals = DiagnoseFitResiduals(r.sequences, o);
  ASSERT_EQ(r.residuals.size(), 2u);
  const std::string html = ReportHtml(r);
  EXPECT_EQ(Count(html, "var mjsysidCharts"), 1u) << "the glue once";
  EXPECT_EQ(Count(html, "@license https://github.com/danvk/dygraphs"), 1u) << "dygraphs once";
  EXPECT_EQ(Count(html, "<div class=\"chart signal\">"), 2u);
  EXPECT_EQ(Count(html, "<div class=\"chart residual\">"), 2u);
  EXPECT_EQ(Count(html, "<div class=\"chart autocorrelation\">"), 2u);
  EXPECT_EQ(Count(html, "<div class=\"chart inputs\">"), 0u) << "no logs, no inputs";
  EXPECT_EQ(Count(html, "mjsysidChart(\"chart-"), 6u);
  // the angle's residual: its band of +-2 sigma and its diagnostics in the caption
  EXPECT_NE(html.find("\"band\":[-0.04,0.04]"), std::string::npos);
  EXPECT_EQ(Count(html, "\"band\":["), 3u) << "angle's +-2 sigma, two autocorrelation bands";
  const ResidualDiagnostics& angle = r.residuals[0];
  EXPECT_NE(html.find("rms " + Num(angle.rms, 3) + " = " + Num(angle.ratio, 3) + " &sigma;"),
            std::string::npos);
  // the still plot folded under the charts of its sequence
  const size_t charts = html.find("<div class=\"chart signal\">");
  const size_t still = html.find("<details class=\"still\">");
  ASSERT_NE(still, std::string::npos);
  EXPECT_LT(charts, still);
  EXPECT_NE(html.find("data:image/png;base64,", still), std::string::npos);
}

// 200,000 samples: each line of a chart keeps at most kInteractivePoints samples (peaks kept)
TEST_F(ReportTest, InteractiveChartsAreDecimated) {
  io::FitResultFile r = Result(200000);
  r.sequences[0].measured(123457, 0) = 40;  // a one-sample spike
  const std::string html = ReportHtml(r);
  const size_t call = html.find("mjsysidChart(\"chart-1\", ");
  ASSERT_NE(call, std::string::npos);
  const size_t rows = html.find("\"rows\":[[", call), end = html.find("]],\"steps\"", rows);
  ASSERT_NE(rows, std::string::npos);
  const std::string data = html.substr(rows, end - rows);
  const size_t n = Count(data, "],[") + 1;
  EXPECT_GT(n, static_cast<size_t>(kInteractivePoints));  // the union of three lines' samples
  EXPECT_LE(n, 3u * kInteractivePoints);
  EXPECT_NE(data.find("[1234.57,40.0,"), std::string::npos) << "the spike survives";
}

// the input plots read the logs again: a file changed since the fit (its recorded SHA-256 differs)
// gives none, and the page says why
TEST_F(ReportTest, InputsOfFilesChangedSinceTheFitAreNotPlotted) {
  io::FitResultFile r = Result(50);
  test::WriteFile(Path("log.h5"), "not the bytes the fit read");
  r.input_hashes = {{"log", Path("log.h5"), std::string(64, '0')}};
  const LoggedExperiment logged = LoadLoggedExperiment(r);
  EXPECT_EQ(logged.note, Path("log.h5") +
                             " (log) changed since the fit: the logs read now are "
                             "not the fit's");
  EXPECT_EQ(InputsOf(logged, "seq0").ctrl.rows(), 0);
  const std::string html = Page(r, {"png"}, {}, "", &logged);
  EXPECT_NE(html.find("no input plots: " + Path("log.h5") + " (log) changed since the fit"),
            std::string::npos);
  EXPECT_EQ(Count(html, "<div class=\"chart inputs\">"), 0u);
}

// a page of many columns keeps fewer samples per line: about kPageLinePoints in all
TEST(InteractiveTest, PointsPerLineShrinkWithThePagesColumns) {
  EXPECT_EQ(PointsPerLine(2), kInteractivePoints);
  EXPECT_EQ(PointsPerLine(200), 250);
  EXPECT_EQ(PointsPerLine(100000), kMinLinePoints);
  EXPECT_EQ(PointsPerLine(0), kInteractivePoints);
}

TEST(CorrelationTest, CorrelationsFromTheCovarianceDashesWithoutAVariance) {
  Eigen::Matrix3d cov;
  cov << 4, 2, 0, 2, 9, 0, 0, 0, 0;  // the third has no variance (fixed)
  const Eigen::MatrixXd r = CorrelationMatrix(cov);
  EXPECT_DOUBLE_EQ(r(0, 0), 1);
  EXPECT_DOUBLE_EQ(r(0, 1), 2.0 / 6.0);
  EXPECT_DOUBLE_EQ(r(1, 0), 2.0 / 6.0);
  EXPECT_TRUE(std::isnan(r(0, 2)));
  EXPECT_TRUE(std::isnan(r(2, 2)));
}

// the matrix on the page: a cell per pair with both names on hover, the strong pairs in words
TEST(CorrelationTest, TheSectionListsStronglyCorrelatedPairs) {
  io::FitResultFile r = Result(50);
  r.uncertainty.covariance << 1.0, -0.97, -0.97, 1.0;
  std::string html = CorrelationSection(r);
  EXPECT_NE(html.find("<h2>Parameter correlation</h2>"), std::string::npos);
  EXPECT_NE(html.find("title=\"damping / bob_mass: &minus;0.97\">&minus;0.97</td>"),
            std::string::npos)
      << html;
  EXPECT_NE(html.find("<li>damping and bob_mass (r = &minus;0.97)</li>"), std::string::npos);
  r.uncertainty.covariance << 1.0, 0.5, 0.5, 1.0;
  html = CorrelationSection(r);
  EXPECT_NE(html.find("no pair correlated beyond"), std::string::npos);
  r.uncertainty.covariance.resize(0, 0);
  EXPECT_NE(CorrelationSection(r).find("no covariance of the parameters"), std::string::npos);
}

TEST_F(ReportTest, EmptyResultsStillMakeAPage) {
  io::FitResultFile r;
  r.name = "nothing";
  r.status = "failed";
  EXPECT_EQ(WriteReport(r, Dir(), nullptr), 3);
  const std::string html = ReadFile(Path("report.html"));
  EXPECT_NE(html.find("no parameters"), std::string::npos);
  EXPECT_NE(html.find("badge bad"), std::string::npos);
  Png png;
  EXPECT_TRUE(Decode(ReadFile(Path("parameters.png")), &png));
}

TEST_F(ReportTest, MissingResultsAndFoldersAreErrors) {
  EXPECT_THROW(WriteReport(Dir(), nullptr), io::ResultError);
  EXPECT_THROW(WriteReport(Result(), Path("nope"), nullptr), ReportError);
}

TEST(SequenceFileNameTest, KeepsSafeCharactersOnly) {
  EXPECT_EQ(SequenceFileName("seq0"), "seq_seq0.png");
  EXPECT_EQ(SequenceFileName("arm5_seq-1.b"), "seq_arm5_seq-1.b.png");
  EXPECT_EQ(SequenceFileName("a b/c\xC3\xA9"), "seq_a_b_c__.png");
}

// ---------------------------------------------------------------------------------------------
// the canvas: cairo drawing, PNG and SVG rendering

TEST(CanvasTest, PngHoldsThePixelsExactly) {
  const std::string bytes = RenderPng(3, 2, [](Canvas& c) {
    c.Rect({0, 0, 3, 2}, Rgb{10, 20, 30});
    c.Rect({1, 0, 1, 1}, Rgb{255, 0, 0});
    c.Rect({2, 1, 1, 1}, Rgb{0, 0, 255});
  });
  Png png;
  ASSERT_TRUE(Decode(bytes, &png));
  EXPECT_EQ(png.width, 3u);
  EXPECT_EQ(png.height, 2u);
  const std::vector<uint8_t> want = {10, 20, 30, 255, 0,  0,  10, 20, 30,
                                     10, 20, 30, 10,  20, 30, 0,  0,  255};
  EXPECT_EQ(png.rgb, want);
}

TEST(CanvasTest, ASizeBeyondCairosLimitIsAReportError) {
  const Drawing nothing = [](Canvas&) {};
  EXPECT_THROW(RenderPng(10, 40000, nothing), ReportError);
  EXPECT_NO_THROW(RenderSvg(10, 40000, "x", nothing));  // vector: no such limit
  EXPECT_NO_THROW(RenderPng(10, 30000, nothing));
}

// the dark pixels of `text` drawn in black at (4, 4) on a white 40 x 28 PNG
int Ink(const std::string& text) {
  Png png;
  EXPECT_TRUE(Decode(RenderPng(40, 28,
                               [&](Canvas& c) {
                                 c.Text(4, 4, text, Rgb{0, 0, 0}, Align::kLeft);
                               }),
                     &png));
  int ink = 0;
  for (const uint8_t v : png.rgb) ink += v < 128;
  return ink;
}

TEST(CanvasTest, EveryPrintableCharacterHasAGlyph) {
  // a real font through fontconfig: printable ascii, accented letters, symbols
  for (int ch = 33; ch < 127; ++ch) {
    EXPECT_GT(Ink(std::string(1, static_cast<char>(ch))), 0) << "character " << char(ch);
  }
  for (const char* utf8 : {"\xC3\xA9", "\xCE\xBC", "\xE2\x88\x9E"}) {  // é, mu, infinity
    EXPECT_GT(Ink(utf8), 0) << utf8;
  }
  // malformed utf-8 draws '?' in place of the bad byte and leaves the canvas working
  EXPECT_GT(Ink("\xFF"), 0);
  std::string svg = RenderSvg(40, 20, "t", [](Canvas& c) {
    c.Text(2, 2, "a\xC3(b", Rgb{0, 0, 0}, Align::kLeft);
    c.Rect({30, 10, 5, 5}, Rgb{0, 0, 255});
  });
  EXPECT_NE(svg.find("fill:rgb(0%,0%,100%)"), std::string::npos) << svg;

  // widths: unhinted advances add up; no width for nothing
  RenderPng(10, 10, [](Canvas& c) {
    EXPECT_GT(c.TextWidth("abc"), 10);
    EXPECT_DOUBLE_EQ(c.TextWidth("abcabc"), 2 * c.TextWidth("abc"));
    EXPECT_GT(c.TextWidth("abc", true), c.TextWidth("abc"));
    EXPECT_EQ(c.TextWidth(""), 0);
    EXPECT_GT(c.CapHeight(), 0.6 * kFontSize);
    EXPECT_LT(c.CapHeight(), 0.8 * kFontSize);
  });
}

TEST(CanvasTest, LinesAreClippedAndAntiAliased) {
  Png png;
  ASSERT_TRUE(Decode(RenderPng(40, 40,
                               [](Canvas& c) {
                                 c.Clip({10, 10, 20, 20});
                                 // far ends: pulled in, still drawn
                                 c.Line({-1e9, 20}, {1e9, 20}, Rgb{0, 0, 0}, 2);
                                 c.Line({0, 0}, {40, 37}, Rgb{0, 0, 0}, 1.5);
                               }),
                     &png));
  EXPECT_EQ(png.Pixel(5, 20).r, 255);  // outside the clip
  EXPECT_EQ(png.Pixel(20, 19).r, 0);   // the horizontal line, 2 px wide
  EXPECT_EQ(png.Pixel(20, 20).r, 0);
  EXPECT_EQ(png.Pixel(20, 25).r, 255);  // away from both
  int partial = 0;                      // edge pixels of the diagonal are blended
  for (size_t i = 0; i < png.rgb.size(); i += 3) partial += png.rgb[i] > 0 && png.rgb[i] < 255;
  EXPECT_GT(partial, 5);
}

// the values of every `attr`="#..." / id="..." in svg
std::vector<std::string> Values(const std::string& svg, const std::string& open) {
  std::vector<std::string> out;
  for (size_t at = svg.find(open); at != std::string::npos; at = svg.find(open, at + 1)) {
    const size_t from = at + open.size();
    out.push_back(svg.substr(from, svg.find_first_of("\")", from) - from));
  }
  return out;
}

TEST(CanvasTest, SvgElementsCanShareAPage) {
  const Drawing draw = [](Canvas& c) {
    c.Clip({0, 0, 50, 20});
    c.Text(2, 2, "Hello", Rgb{0, 0, 0}, Align::kLeft);
    c.Line({0, 0}, {100, 40}, Rgb{255, 0, 0}, 2, 4);
  };
  const std::string a = RenderSvg(100, 40, "a", draw), b = RenderSvg(100, 40, "b", draw);
  EXPECT_EQ(a.rfind("<svg", 0), 0u) << "no xml declaration before the element";
  EXPECT_NE(a.find("width=\"100px\""), std::string::npos) << a;
  EXPECT_NE(a.find("viewBox=\"0 0 100 40\""), std::string::npos) << a;
  EXPECT_NE(a.find("stroke-dasharray"), std::string::npos) << a;

  // every id carries the element's prefix; every reference finds its id in the same element
  for (const auto& [svg, prefix] : {std::pair{a, "a-"}, std::pair{b, "b-"}}) {
    const std::vector<std::string> ids = Values(svg, "id=\""), refs = Values(svg, "href=\"#"),
                                   urls = Values(svg, "url(#");
    EXPECT_GE(ids.size(), 3u);  // glyphs, the clip path, the surface
    EXPECT_FALSE(refs.empty());
    EXPECT_FALSE(urls.empty());
    for (const std::string& id : ids) EXPECT_EQ(id.rfind(prefix, 0), 0u) << id;
    for (const std::vector<std::string>* list : {&refs, &urls}) {
      for (const std::string& ref : *list) {
        EXPECT_NE(std::find(ids.begin(), ids.end(), ref), ids.end()) << ref;
      }
    }
  }
}

}  // namespace
}  // namespace mjsysid::report

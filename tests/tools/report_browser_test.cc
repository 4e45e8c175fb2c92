// The report in a real browser: a fit with the real CLI (`sysid simulate`, `sysid fit`,
// `sysid report` on experiments/pendulum.yaml), then report.html opened in headless Chromium.
//
// - A copy of the page with a checking script appended is loaded with --dump-dom: on load the
//   script checks that every section is there and laid out, every <img> decoded
//   (naturalWidth > 0), every inline <svg> has a non-empty box, every interactive chart (dygraphs)
//   drawn, counted by kind, and every id on the page is unique with every glyph reference
//   resolved, and writes its verdict into the DOM.
// - Another script drives the time plots with mouse events as a user would: hover shows values,
//   a drag zooms the chart and its sequence's other charts follow, a double-click zooms out.
// - The page itself is rendered with --screenshot, which must not be blank.
// - The motion clip (an animated WebP <img>) is screenshotted twice, once as soon as the page has
//   loaded and once ~2 s later (a page whose load a local server holds open for 2 s): both halves,
//   initial and fitted, must be drawn and must have moved. Chromium animates images on its
//   compositor in real time only: under --virtual-time-budget, and in a canvas drawImage, an
//   animated image stays at its first frame (measured with Chromium 156), hence two real-time
//   screenshots.
// - Broken copies (a corrupt image, an emptied plot, a still image as the clip) must fail.
// Chromium is required: without it the test fails (tools/bootstrap.sh installs it). Each
// Chromium run is killed with its helper processes after 60 s.
#include <arpa/inet.h>
#include <cairo.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "tests/file_util.h"
#include "tests/tools/png_util.h"

namespace mjsysid {
namespace {

namespace fs = std::filesystem;
using test::ReadFile;
using test::WriteFile;

// the last `n` characters of text (a long log's end)
std::string Tail(const std::string& text, size_t n = 3000) {
  return text.size() <= n ? text : "..." + text.substr(text.size() - n);
}

// the full path of `name` on PATH, "" when it is not there
std::string FindProgram(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path != nullptr ? path : "/usr/bin:/bin");
  for (std::string dir; std::getline(dirs, dir, ':');) {
    const fs::path candidate = fs::path(dir) / name;
    if (!dir.empty() && ::access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  return "";
}

// A local TCP server that holds every connection it accepts for `hold` and then closes it: an
// <img> pointing at it keeps back the load event of a page (and so Chromium's --screenshot) for
// that long in real time.
class HoldServer {
 public:
  explicit HoldServer(std::chrono::milliseconds hold) : hold_(hold) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof(a);
    if (fd_ < 0 || ::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof(a)) != 0 ||
        ::listen(fd_, 8) != 0 || ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &len) != 0) {
      ADD_FAILURE() << "no local server socket";
      return;
    }
    port_ = ntohs(a.sin_port);
    thread_ = std::thread([this] { Serve(); });
  }
  ~HoldServer() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    if (fd_ >= 0) ::close(fd_);
  }
  int port() const { return port_; }

 private:
  // accept, hold, close; checks `stop_` every 50 ms
  void Serve() {
    while (!stop_) {
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 50) <= 0) continue;
      const int c = ::accept(fd_, nullptr, nullptr);
      if (c < 0) continue;
      const auto until = std::chrono::steady_clock::now() + hold_;
      while (!stop_ && std::chrono::steady_clock::now() < until) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      }
      ::close(c);
    }
  }
  std::chrono::milliseconds hold_;
  int fd_ = -1, port_ = 0;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

// the pixels of a w x h region at (x, y) of a screenshot that differ from the region's
// bottom-right pixel (the background) by more than 30 in some channel; and those that differ by
// as much between two screenshots
struct RegionCount {
  size_t foreground_a = 0, foreground_b = 0, changed = 0;
};
RegionCount CountRegion(cairo_surface_t* a, cairo_surface_t* b, int x0, int y0, int w, int h) {
  auto pixel = [](cairo_surface_t* s, int x, int y) {
    const unsigned char* row =
        cairo_image_surface_get_data(s) + y * cairo_image_surface_get_stride(s);
    return reinterpret_cast<const uint32_t*>(row)[x];
  };
  auto differ = [](uint32_t p, uint32_t q) {
    for (int shift = 0; shift <= 16; shift += 8) {
      if (std::abs(static_cast<int>((p >> shift) & 0xFF) - static_cast<int>((q >> shift) & 0xFF)) >
          30) {
        return true;
      }
    }
    return false;
  };
  RegionCount n;
  const uint32_t bg_a = pixel(a, x0 + w - 1, y0 + h - 1), bg_b = pixel(b, x0 + w - 1, y0 + h - 1);
  for (int y = y0; y < y0 + h; ++y) {
    for (int x = x0; x < x0 + w; ++x) {
      n.foreground_a += differ(pixel(a, x, y), bg_a);
      n.foreground_b += differ(pixel(b, x, y), bg_b);
      n.changed += differ(pixel(a, x, y), pixel(b, x, y));
    }
  }
  return n;
}

// What the checking scripts share (before each): the verdict element, box(e) (laid out with a
// size) and drawnCharts(problems): every interactive chart drawn (a canvas with a box in its
// plot, at least 2 rows), one per plot <div>; returns the count of charts by kind.
constexpr char kCheckPrelude[] = R"js(
<pre id="verdict">no verdict: the script did not run</pre>
<script>
const box = (e) => { const r = e.getBoundingClientRect(); return r.width > 0 && r.height > 0; };
function drawnCharts(problems) {
  const kinds = {};
  const charts = window.mjsysidCharts || [];
  for (const g of charts) {
    kinds[g.mjsysidKind] = (kinds[g.mjsysidKind] || 0) + 1;
    const canvas = g.graphDiv.querySelector('canvas');
    if (!canvas || !box(canvas) || g.numRows() < 2) problems.push('chart ' + g.maindiv_.id + ' not drawn');
  }
  if (charts.length !== document.querySelectorAll('.chart-plot').length) {
    problems.push(charts.length + ' charts for ' + document.querySelectorAll('.chart-plot').length +
                  ' plots');
  }
  return kinds;
}
</script>
)js";

// the fit report's check, appended to a copy of the page after kCheckPrelude: its verdict, "OK
// ..." or "FAIL <problems>", goes into <pre id="verdict"> once the page has loaded
constexpr char kCheckBody[] = R"js(
<script>
window.addEventListener('load', () => {
  const problems = [];
  // the still plots are folded under the charts: unfolded to be checked
  for (const d of document.querySelectorAll('details')) d.open = true;

  // every section, laid out
  const sections = ['Solver settings', 'Parameters', 'Parameter correlation', 'Warnings', 'Cost',
                    'Parameters over the iterations', 'Residuals', 'Sequences', 'Motion'];
  const headings = [...document.querySelectorAll('h2')];
  for (const name of sections) {
    const h = headings.find((e) => e.textContent === name);
    if (!h) problems.push('missing section "' + name + '"');
    else if (!box(h)) problems.push('section "' + name + '" has no box');
  }
  for (const t of document.querySelectorAll('h1, table')) {
    if (!box(t)) problems.push(t.tagName + ' has no box');
  }

  // every image decoded, every plot drawn
  const images = [...document.images];
  for (const img of images) {
    if (!img.complete || img.naturalWidth === 0 || !box(img)) {
      problems.push('image "' + img.alt + '" did not render');
    }
  }
  const svgs = [...document.querySelectorAll('svg')].filter((s) => !s.parentElement.closest('svg'));
  for (const [i, svg] of svgs.entries()) {
    const b = svg.getBBox();
    if (!(b.width > 0 && b.height > 0) || !box(svg)) problems.push('svg ' + i + ' is empty');
    if (svg.querySelectorAll('use').length === 0) problems.push('svg ' + i + ' has no text');
  }

  // every interactive chart drawn, by kind
  const kinds = drawnCharts(problems);
  const chartCounts = ['signal', 'residual', 'inputs', 'autocorrelation']
                          .map((k) => k + ':' + (kinds[k] || 0)).join(',');

  // the motion clip: one image, decoded at its full size (three 320x240 views)
  const clips = document.querySelectorAll('img.motion');
  const motion = clips.length === 1 ? clips[0].naturalWidth + 'x' + clips[0].naturalHeight
                                    : clips.length + ' clips';

  // ids unique on the page; every reference resolved
  const ids = new Set();
  for (const e of document.querySelectorAll('[id]')) {
    if (ids.has(e.id)) problems.push('duplicate id ' + e.id);
    ids.add(e.id);
  }
  for (const u of document.querySelectorAll('use')) {
    const ref = u.getAttribute('xlink:href') || u.getAttribute('href') || '';
    if (!document.getElementById(ref.slice(1))) problems.push('dangling reference ' + ref);
  }

  document.getElementById('verdict').textContent = problems.length
      ? 'FAIL ' + [...new Set(problems)].join('; ')
      : 'OK sections=' + sections.length + ' images=' + images.length + ' svgs=' + svgs.length +
        ' motion=' + motion + ' charts=' + chartCounts;
});
</script>
)js";

// the script that drives the time plots as a user would (mouse events on the first signal chart):
// hover shows the values under the pointer in its legend; a drag across 30 %..60 % of its width
// zooms it to that window and the other charts of its sequence follow; a double-click zooms all of
// them out again. Its verdict, "OK ..." or "FAIL <problems>", as kCheckBody's.
constexpr char kInteractionScript[] = R"js(
<script>
window.addEventListener('load', () => {
  const problems = [];
  const charts = window.mjsysidCharts || [];
  const g = charts.find((c) => c.mjsysidKind === 'signal');
  if (!g) {
    document.getElementById('verdict').textContent = 'FAIL no signal chart';
    return;
  }
  const others = charts.filter((c) => c !== g && c.mjsysidGroup === g.mjsysidGroup);
  g.graphDiv.scrollIntoView();
  const el = g.mouseEventElement_;
  const r = el.getBoundingClientRect(), area = g.getArea();
  const at = (f) => ({x: r.left + area.x + f * area.w, y: r.top + area.y + area.h / 2});
  const fire = (type, f, buttons) => {
    const p = at(f);
    el.dispatchEvent(new MouseEvent(type, {bubbles: true, cancelable: true, view: window,
                                           clientX: p.x, clientY: p.y, button: 0, buttons}));
  };

  // hover: a row selected, its values in the legend
  fire('mousemove', 0.5, 0);
  const legend = g.getOption('labelsDiv').textContent;
  if (g.getSelection() < 0) problems.push('hover selected no row');
  if (!/estimate:\s*-?[0-9]/.test(legend)) problems.push('legend without values: ' + legend);

  // drag-zoom from 30 % to 60 % of the width
  const full = g.xAxisExtremes();
  fire('mousedown', 0.3, 1);
  fire('mousemove', 0.45, 1);
  fire('mousemove', 0.6, 1);
  fire('mouseup', 0.6, 0);
  const range = g.xAxisRange();
  const share = (range[1] - range[0]) / (full[1] - full[0]);
  if (!g.isZoomed('x') || !(share > 0.25 && share < 0.35)) {
    problems.push('drag did not zoom to 30 %: ' + share.toFixed(3));
  }
  let followed = 0;
  for (const o of others) {
    const q = o.xAxisRange();
    if (Math.abs(q[0] - range[0]) < 1e-9 && Math.abs(q[1] - range[1]) < 1e-9) ++followed;
  }
  if (others.length === 0 || followed !== others.length) {
    problems.push(followed + ' of ' + others.length + ' charts followed the zoom');
  }

  // double-click (two clicks, then the dblclick event, as a browser sends them): all zoomed out
  for (let k = 0; k < 2; ++k) {
    fire('mousedown', 0.5, 1);
    fire('mouseup', 0.5, 0);
  }
  fire('dblclick', 0.5, 0);
  if (g.isZoomed('x') || others.some((o) => o.isZoomed('x'))) problems.push('not zoomed out');

  document.getElementById('verdict').textContent = problems.length
      ? 'FAIL ' + problems.join('; ')
      : 'OK zoom=' + share.toFixed(2) + ' followed=' + followed;
});
</script>
)js";

// The checking script of `sysid design`'s page: its four sections laid out, every chart drawn (by
// kind), and the standard-error bars with a width. Its verdict: "OK sections=4 charts=controls:N,
// motion:M bars=B" or "FAIL <problems>".
constexpr char kDesignCheckBody[] = R"js(
<script>
window.addEventListener('load', () => {
  const problems = [];
  const sections = ['Predicted standard errors', 'Controls', 'Predicted motion', 'Constraints'];
  const headings = [...document.querySelectorAll('h2')];
  let found = 0;
  for (const name of sections) {
    const h = headings.find((e) => e.textContent === name);
    if (!h || !box(h)) problems.push('section "' + name + '" missing or without a box');
    else found++;
  }
  const kinds = drawnCharts(problems);
  const bars = [...document.querySelectorAll('.bar')].filter(box).length;
  document.getElementById('verdict').textContent = problems.length
      ? 'FAIL ' + problems.join('; ')
      : 'OK sections=' + found + ' charts=controls:' + (kinds.controls || 0) + ',motion:' +
        (kinds.motion || 0) + ' bars=' + bars;
});
</script>
)js";

class ReportBrowserTest : public ::testing::Test {
 protected:
  // one fit and report for all tests
  static void SetUpTestSuite() {
    dir_ = test::FreshTempDir("report_browser_test");

    // the shipped experiment, its model found from the temporary folder
    std::string yaml = ReadFile(std::string(MJSYSID_EXPERIMENTS_DIR) + "/pendulum.yaml");
    const std::string model = "model: ../models/pendulum.xml";
    const size_t at = yaml.find(model);
    ASSERT_NE(at, std::string::npos) << "experiments/pendulum.yaml names its model differently";
    yaml.replace(at, model.size(), "model: " + std::string(MJSYSID_MODELS_DIR) + "/pendulum.xml");
    WriteFile(dir_ + "/pendulum.yaml", yaml);

    // simulate, fit, report: the real command line
    for (const std::string& args : {"simulate " + dir_ + "/pendulum.yaml",
                                    "fit " + dir_ + "/pendulum.yaml --out " + dir_ + "/out --quiet",
                                    "report " + dir_ + "/out"}) {
      const std::string cmd = "timeout -s KILL 300 " + std::string(MJSYSID_SYSID_BIN) + " " + args +
                              " >" + dir_ + "/sysid.txt 2>&1";
      ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd << "\n" << ReadFile(dir_ + "/sysid.txt");
    }
    ASSERT_TRUE(fs::exists(dir_ + "/out/report.html"));
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  // runs headless Chromium on the file `html` with `options`; returns its standard output.
  // virtual_time: up to 10 s of virtual time for the page's timers (no waiting in real time)
  static std::string Chromium(const std::string& html, const std::string& options,
                              bool virtual_time = true) {
    const std::string chromium = FindProgram("chromium");
    EXPECT_FALSE(chromium.empty()) << "chromium is not installed (tools/bootstrap.sh installs it)";
    if (chromium.empty()) return "";
    // timeout signals its whole process group: Chromium and its helpers
    const std::string cmd =
        "timeout -s KILL 60 " + chromium +
        " --headless=new --no-sandbox --disable-gpu --disable-dev-shm-usage"
        " --no-first-run --user-data-dir=" +
        dir_ + "/chromium-profile " + (virtual_time ? "--virtual-time-budget=10000 " : "") +
        options + " file://" + html + " >" + dir_ + "/chromium.out 2>" + dir_ + "/chromium.err";
    const int status = std::system(cmd.c_str());
    EXPECT_EQ(status, 0) << cmd << "\n" << Tail(ReadFile(dir_ + "/chromium.err"));
    return ReadFile(dir_ + "/chromium.out");
  }

  // the verdict of the checking script (kCheckBody, or `script`) after kCheckPrelude on a copy
  // of `page`
  static std::string Verdict(const std::string& page, const std::string& name,
                             const char* script = kCheckBody) {
    const std::string copy = dir_ + "/out/" + name;
    std::string html = page;
    const size_t body_end = html.rfind("</body>");
    EXPECT_NE(body_end, std::string::npos);
    html.insert(body_end == std::string::npos ? html.size() : body_end,
                std::string(kCheckPrelude) + script);
    WriteFile(copy, html);
    const std::string dom = Chromium(copy, "--dump-dom");
    const std::string open = "<pre id=\"verdict\">";
    const size_t from = dom.find(open);
    if (from == std::string::npos) return "no verdict in the DOM: " + Tail(dom, 500);
    const size_t to = dom.find("</pre>", from);
    return dom.substr(from + open.size(), to - from - open.size());
  }

  static std::string Page() { return ReadFile(dir_ + "/out/report.html"); }

  // the motion clip's <img> tag of a page ("" when there is none)
  static std::string MotionImg(const std::string& page) {
    const size_t at = page.find("<img class=\"motion\"");
    return at == std::string::npos ? "" : page.substr(at, page.find('>', at) + 1 - at);
  }

  // "OK" when the clip `img` (960x240: initial, fitted, and the measured motion from the log's
  // qpos) moves in Chromium: a page with
  // only the clip at the top-left is screenshotted as soon as it has loaded, and once more with
  // its load held back ~2 s (HoldServer); each half must be drawn in both shots (the rod, the bob
  // and the label: more than 200 pixels) and must have changed (more than 100 pixels; measured on
  // the pendulum, two runs: 987-1047 drawn, 1131-1174 changed; a still image: 0 changed). Otherwise
  // the problems, "FAIL ...".
  static std::string MotionVerdict(const std::string& img, const std::string& name) {
    HoldServer server(std::chrono::milliseconds(2000));
    const std::string hold =
        "<img alt=\"\" style=\"display:block;width:1px;height:1px\" src=\""
        "http://127.0.0.1:" +
        std::to_string(server.port()) + "/hold\">";
    cairo_surface_t* shots[2];
    for (int k = 0; k < 2; ++k) {
      const std::string html = dir_ + "/" + name + std::to_string(k) + ".html";
      const std::string png = dir_ + "/" + name + std::to_string(k) + ".png";
      WriteFile(html, "<!DOCTYPE html><html><body style=\"margin:0;background:#fff\">" + img +
                          (k == 1 ? hold : "") + "</body></html>");
      fs::remove(png);
      Chromium(html, "--window-size=1000,300 --screenshot=" + png, /*virtual_time=*/false);
      shots[k] = test::SurfaceFromPng(ReadFile(png));
      if (cairo_surface_status(shots[k]) != CAIRO_STATUS_SUCCESS) return "FAIL no screenshot";
    }
    std::string problems;
    const char* halves[3] = {"initial", "fitted", "measured"};
    for (int h = 0; h < 3; ++h) {
      const RegionCount n = CountRegion(shots[0], shots[1], 320 * h, 0, 320, 240);
      if (n.foreground_a <= 200 || n.foreground_b <= 200) {
        problems += std::string(" ") + halves[h] + " not drawn (" + std::to_string(n.foreground_a) +
                    ", " + std::to_string(n.foreground_b) + ");";
      }
      if (n.changed <= 100) {
        problems += std::string(" ") + halves[h] + " did not move (" + std::to_string(n.changed) +
                    " pixels changed);";
      }
    }
    for (cairo_surface_t* shot : shots) cairo_surface_destroy(shot);
    return problems.empty() ? "OK" : "FAIL" + problems;
  }

  static std::string dir_;
};
std::string ReportBrowserTest::dir_;

TEST_F(ReportBrowserTest, EverySectionAndPlotRenders) {
  // 9 sections, the 3 sequence PNGs and the motion clip, the cost and parameter SVGs; per sequence
  // (3) and sensor (angle, rate) a signal and a residual chart, per sequence the inputs (the
  // motor), per sensor the residuals' autocorrelation
  EXPECT_EQ(Verdict(Page(), "check.html"),
            "OK sections=9 images=4 svgs=2 motion=960x240 "
            "charts=signal:6,residual:6,inputs:3,autocorrelation:2");
}

// `sysid design` of the cart-pole (1 actuator, 2 joints, 3 parameters; 10 candidates): the page's
// sections, one controls chart, two motion charts, two bars per parameter
TEST_F(ReportBrowserTest, TheDesignPageRenders) {
  const std::string cmd = "timeout -s KILL 300 " + std::string(MJSYSID_SYSID_BIN) + " design " +
                          MJSYSID_EXPERIMENTS_DIR + "/cartpole.yaml --evaluations 10 --out " +
                          dir_ + "/design >" + dir_ + "/design.txt 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << ReadFile(dir_ + "/design.txt");
  EXPECT_EQ(Verdict(ReadFile(dir_ + "/design/design.html"), "design_check.html", kDesignCheckBody),
            "OK sections=4 charts=controls:1,motion:2 bars=6");
}

TEST_F(ReportBrowserTest, TheTimePlotsZoomTogetherAndShowValuesOnHover) {
  // the sequence's 4 other charts (rate's signal, both residuals, the inputs) follow the zoom
  EXPECT_EQ(Verdict(Page(), "interaction.html", kInteractionScript), "OK zoom=0.30 followed=4");
}

TEST_F(ReportBrowserTest, ABrokenChartFailsTheCheck) {
  // a chart whose library call is gone: its plot stays empty
  std::string page = Page();
  const size_t call = page.find("<script>mjsysidChart(\"chart-");
  ASSERT_NE(call, std::string::npos);
  page.erase(call, page.find("</script>", call) + 9 - call);
  const std::string verdict = Verdict(page, "broken_chart.html");
  EXPECT_EQ(verdict.rfind("FAIL ", 0), 0u) << verdict;
  EXPECT_NE(verdict.find("charts for"), std::string::npos) << verdict;
}

TEST_F(ReportBrowserTest, TheMotionClipPlays) {
  const std::string img = MotionImg(Page());
  ASSERT_FALSE(img.empty()) << "no motion clip on the page";
  EXPECT_NE(img.find("src=\"data:image/webp;base64,"), std::string::npos) << img.substr(0, 200);
  EXPECT_EQ(MotionVerdict(img, "motion"), "OK");
}

TEST_F(ReportBrowserTest, NoVideoSaysSo) {
  // the same results reported again with --no-video: the section says so, no clip, no file
  const std::string copy = dir_ + "/out_novideo";
  fs::remove_all(copy);
  fs::copy(dir_ + "/out", copy);
  const std::string cmd = "timeout -s KILL 300 " + std::string(MJSYSID_SYSID_BIN) + " report " +
                          copy + " --no-video >" + dir_ + "/sysid.txt 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd << "\n" << ReadFile(dir_ + "/sysid.txt");
  const std::string page = ReadFile(copy + "/report.html");
  EXPECT_EQ(MotionImg(page), "");
  EXPECT_NE(page.find("no video: turned off (sysid report --no-video)"), std::string::npos);
  EXPECT_FALSE(fs::exists(copy + "/motion.webp"));
  EXPECT_EQ(Verdict(page, "check_novideo.html"),
            "OK sections=9 images=3 svgs=2 motion=0 clips "
            "charts=signal:6,residual:6,inputs:3,autocorrelation:2");
}

TEST_F(ReportBrowserTest, TheScreenshotIsNotBlank) {
  const std::string shot = dir_ + "/shot.png";
  fs::remove(shot);
  Chromium(dir_ + "/out/report.html", "--window-size=1280,3600 --screenshot=" + shot);
  const std::string bytes = ReadFile(shot);
  ASSERT_FALSE(bytes.empty()) << "no screenshot";
  cairo_surface_t* s = test::SurfaceFromPng(bytes);
  ASSERT_EQ(cairo_surface_status(s), CAIRO_STATUS_SUCCESS);
  const int w = cairo_image_surface_get_width(s), h = cairo_image_surface_get_height(s);
  EXPECT_EQ(w, 1280);
  EXPECT_EQ(h, 3600);

  // text and lines (dark), and the fitted curves (red: the cost of the plots is mostly white)
  size_t dark = 0, red = 0;
  const unsigned char* data = cairo_image_surface_get_data(s);
  for (int y = 0; y < h; ++y) {
    const auto* row =
        reinterpret_cast<const uint32_t*>(data + y * cairo_image_surface_get_stride(s));
    for (int x = 0; x < w; ++x) {
      const int r = (row[x] >> 16) & 0xFF, g = (row[x] >> 8) & 0xFF, b = row[x] & 0xFF;
      dark += r < 100 && g < 100 && b < 100;
      red += r > 180 && g < 90 && b < 90;
    }
  }
  cairo_surface_destroy(s);
  EXPECT_GT(dark, 20000u) << "text";
  EXPECT_GT(red, 5000u) << "fitted curves";
}

TEST_F(ReportBrowserTest, ABrokenPlotFailsTheCheck) {
  // an image whose data is not a PNG (the first sequence's still plot: the inlined library has a
  // PNG data URI of its own)
  std::string page = Page();
  const std::string png = "data:image/png;base64,iVBORw0KGgo";  // the PNG signature
  const std::string seq0 = "<img alt=\"sequence seq0\" src=\"";
  const size_t at = page.find(seq0 + png) + seq0.size();
  ASSERT_GT(at, seq0.size());
  page.replace(at, png.size(), "data:image/png;base64,AAAAAAAAAAA");
  const std::string verdict = Verdict(page, "broken_image.html");
  EXPECT_EQ(verdict.rfind("FAIL ", 0), 0u) << verdict;
  EXPECT_NE(verdict.find("image \"sequence seq0\" did not render"), std::string::npos) << verdict;

  // a plot with nothing drawn in it
  page = Page();
  const size_t svg = page.find("<svg"), content = page.find('>', svg) + 1;
  page.erase(content, page.find("</svg>", content) - content);
  const std::string empty = Verdict(page, "empty_svg.html");
  EXPECT_EQ(empty.rfind("FAIL ", 0), 0u) << empty;
  EXPECT_NE(empty.find("svg 0 is empty"), std::string::npos) << empty;

  // a still image in place of the clip: the first sequence plot, as large
  page = Page();
  std::string still = MotionImg(page);
  const size_t src = still.find("src=\"");
  ASSERT_NE(src, std::string::npos);
  const size_t from = page.find(seq0 + png) + seq0.size();
  still = still.substr(0, src) + "src=\"" + page.substr(from, page.find('"', from) - from) + "\">";
  const std::string verdict_still = MotionVerdict(still, "still");
  EXPECT_EQ(verdict_still.rfind("FAIL", 0), 0u) << verdict_still;
  EXPECT_NE(verdict_still.find("initial did not move"), std::string::npos) << verdict_still;
  EXPECT_NE(verdict_still.find("fitted did not move"), std::string::npos) << verdict_still;
}

}  // namespace
}  // namespace mjsysid

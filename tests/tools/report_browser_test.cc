// The report in a real browser: a fit with the real CLI (`sysid simulate`, `sysid fit`,
// `sysid report` on experiments/pendulum.yaml), then report.html opened in headless Chromium.
//
// - A copy of the page with a checking script appended is loaded with --dump-dom: on load the
//   script checks that every section is there and laid out, every <img> decoded
//   (naturalWidth > 0), every inline <svg> has a non-empty box and every id on the page is
//   unique with every glyph reference resolved, and writes its verdict into the DOM.
// - The page itself is rendered with --screenshot, which must not be blank.
// - Broken copies (a corrupt image, an emptied plot) must get a failing verdict.
// Chromium is required: without it the test fails (tools/bootstrap.sh installs it). Each
// Chromium run is killed with its helper processes after 60 s.
#include <cairo.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
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

// the script appended to a copy of the page: its verdict, "OK ..." or "FAIL <problems>", goes
// into <pre id="verdict"> once the page has loaded
constexpr char kCheckScript[] = R"js(
<pre id="verdict">no verdict: the script did not run</pre>
<script>
window.addEventListener('load', () => {
  const problems = [];
  const box = (e) => { const r = e.getBoundingClientRect(); return r.width > 0 && r.height > 0; };

  // every section, laid out
  const sections = ['Solver settings', 'Parameters', 'Warnings', 'Cost',
                    'Parameters over the iterations', 'Sequences'];
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
      : 'OK sections=' + sections.length + ' images=' + images.length + ' svgs=' + svgs.length;
});
</script>
)js";

class ReportBrowserTest : public ::testing::Test {
 protected:
  // one fit and report for all tests
  static void SetUpTestSuite() {
    dir_ =
        (fs::temp_directory_path() / ("mjsysid_report_browser_test_" + std::to_string(::getpid())))
            .string();
    fs::remove_all(dir_);
    fs::create_directories(dir_);

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

  // runs headless Chromium on the file `html` with `options`; returns its standard output
  static std::string Chromium(const std::string& html, const std::string& options) {
    const std::string chromium = FindProgram("chromium");
    EXPECT_FALSE(chromium.empty()) << "chromium is not installed (tools/bootstrap.sh installs it)";
    if (chromium.empty()) return "";
    // timeout signals its whole process group: Chromium and its helpers
    const std::string cmd = "timeout -s KILL 60 " + chromium +
                            " --headless=new --no-sandbox --disable-gpu --disable-dev-shm-usage"
                            " --no-first-run --user-data-dir=" +
                            dir_ + "/chromium-profile --virtual-time-budget=10000 " + options +
                            " file://" + html + " >" + dir_ + "/chromium.out 2>" + dir_ +
                            "/chromium.err";
    const int status = std::system(cmd.c_str());
    EXPECT_EQ(status, 0) << cmd << "\n" << Tail(ReadFile(dir_ + "/chromium.err"));
    return ReadFile(dir_ + "/chromium.out");
  }

  // the verdict of the checking script on a copy of `page`
  static std::string Verdict(const std::string& page, const std::string& name) {
    const std::string copy = dir_ + "/out/" + name;
    std::string html = page;
    const size_t body_end = html.rfind("</body>");
    EXPECT_NE(body_end, std::string::npos);
    html.insert(body_end == std::string::npos ? html.size() : body_end, kCheckScript);
    WriteFile(copy, html);
    const std::string dom = Chromium(copy, "--dump-dom");
    const std::string open = "<pre id=\"verdict\">";
    const size_t from = dom.find(open);
    if (from == std::string::npos) return "no verdict in the DOM: " + Tail(dom, 500);
    const size_t to = dom.find("</pre>", from);
    return dom.substr(from + open.size(), to - from - open.size());
  }

  static std::string Page() { return ReadFile(dir_ + "/out/report.html"); }

  static std::string dir_;
};
std::string ReportBrowserTest::dir_;

TEST_F(ReportBrowserTest, EverySectionAndPlotRenders) {
  // 6 sections, the 3 sequence PNGs, the cost and parameter SVGs
  EXPECT_EQ(Verdict(Page(), "check.html"), "OK sections=6 images=3 svgs=2");
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
  // an image whose data is not a PNG
  std::string page = Page();
  const std::string png = "data:image/png;base64,iVBORw0KGgo";  // the PNG signature
  const size_t at = page.find(png);
  ASSERT_NE(at, std::string::npos);
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
}

}  // namespace
}  // namespace mjsysid

#include "tools/report/design_page.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "sysid/io/atomic_file.h"
#include "tools/report/axes.h"
#include "tools/report/interactive.h"
#include "tools/report/page.h"

namespace mjsysid::report {
namespace {

constexpr char kDesignCss[] = R"css(
.bars{width:260px}
.bar{height:7px;margin:2px 0;border-radius:2px}
.bar.current{background:#a5a5a5}.bar.design{background:#d62728}
td.worst{font-weight:700}
)css";

// a number with `digits` significant digits; "inf" for an infinite one
std::string Fmt(double v, int digits = 3) {
  if (std::isinf(v)) return "\xE2\x88\x9E";
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.*g", digits, v);
  return buf;
}

std::string Percent(double relative) {
  return std::isfinite(relative) ? Fmt(100 * relative) + " %" : "\xE2\x88\x9E";
}

// the predicted relative standard errors, current and design, with bars on a log scale
void StdSection(std::ostringstream& h, const design::DesignResult& r) {
  const Eigen::VectorXd& cur = r.current.info.relative_std;
  const Eigen::VectorXd& des = r.design.info.relative_std;
  // the bars' scale: log10 from a decade below the smallest finite value to the largest
  double lo = INFINITY, hi = 0;
  for (const Eigen::VectorXd* v : {&cur, &des}) {
    for (Eigen::Index j = 0; j < v->size(); ++j) {
      if (std::isfinite((*v)[j]) && (*v)[j] > 0) {
        lo = std::min(lo, (*v)[j]);
        hi = std::max(hi, (*v)[j]);
      }
    }
  }
  lo = std::isfinite(lo) ? std::log10(lo) - 1 : 0;
  hi = hi > 0 ? std::log10(hi) : 1;
  auto width = [&](double v) {
    if (!std::isfinite(v)) return 100.0;
    if (!(v > 0)) return 0.0;
    return std::clamp(100 * (std::log10(v) - lo) / std::max(hi - lo, 1e-9), 1.0, 100.0);
  };
  h << "<h2>Predicted standard errors</h2>\n<p class=\"muted\">relative to the value; what a fit "
       "of a log of each excitation would report (the Fisher information of the fitted sensors "
       "with their sigmas). Bars on a log scale: grey the current excitation, red the "
       "design.</p>\n<table><tr><th>parameter</th><th>value</th><th>current</th><th>design</th>"
       "<th>current / design</th><th class=\"bars\"></th></tr>\n";
  for (size_t j = 0; j < r.parameters.size(); ++j) {
    const auto k = static_cast<Eigen::Index>(j);
    const bool worst_cur = cur[k] == r.current.info.worst_relative_std;
    const bool worst_des = des[k] == r.design.info.worst_relative_std;
    char bars[200];
    std::snprintf(bars, sizeof(bars),
                  "<div class=\"bar current\" style=\"width:%.1f%%\"></div>"
                  "<div class=\"bar design\" style=\"width:%.1f%%\"></div>",
                  width(cur[k]), width(des[k]));
    h << "<tr><td>" << HtmlEscape(r.parameters[j]) << "</td><td class=\"n\">" << Fmt(r.values[k], 6)
      << "</td><td class=\"n" << (worst_cur ? " worst" : "") << "\">" << Percent(cur[k])
      << "</td><td class=\"n" << (worst_des ? " worst" : "") << "\">" << Percent(des[k])
      << "</td><td class=\"n\">" << Fmt(cur[k] / des[k]) << "x</td><td>" << bars << "</td></tr>\n";
  }
  h << "<tr><td><b>worst</b></td><td></td><td class=\"n worst\">"
    << Percent(r.current.info.worst_relative_std) << "</td><td class=\"n worst\">"
    << Percent(r.design.info.worst_relative_std) << "</td><td class=\"n\">"
    << Fmt(r.current.info.worst_relative_std / r.design.info.worst_relative_std)
    << "x</td><td></td></tr>\n</table>\n";
}

// one chart per column: the current excitation's and the design's, a band shaded
std::string Pair(const std::string& kind, const std::string& title, const Eigen::VectorXd& t,
                 const Eigen::VectorXd& current, const Eigen::VectorXd& designed, double lo,
                 double hi, const std::string& group, ChartIds& ids) {
  Chart c;
  c.kind = kind;
  c.title = title;
  c.xlabel = "time (s)";
  c.x = t;
  c.group = group;
  c.lines.push_back(Line{"current", current, kMeasured});
  c.lines.push_back(Line{"design", designed, kAfter, 1.5});
  c.band_lo = lo;
  c.band_hi = hi;
  c.band_color = "rgba(31,95,191,0.08)";
  return ChartHtml(c, ids);
}

// the constraint margins of both excitations
void ConstraintSection(std::ostringstream& h, const design::DesignResult& r) {
  const design::DesignOptions& o = r.options;
  h << "<h2>Constraints</h2>\n<p class=\"muted\">range margin " << Fmt(100 * o.range_margin)
    << " % of each limited joint's range; joint speed limit "
    << (o.max_joint_speed > 0 ? Fmt(o.max_joint_speed) : std::string("none")) << "; contacts "
    << (o.contacts ? "allowed" : "forbidden") << "</p>\n<table><tr><th></th><th>current</th>"
    << "<th>design</th></tr>\n";
  auto row = [&](const std::string& name, const std::string& a, const std::string& b) {
    h << "<tr><td>" << name << "</td><td class=\"n\">" << a << "</td><td class=\"n\">" << b
      << "</td></tr>\n";
  };
  row("meets the constraints",
      r.current.violation.empty() ? "yes" : HtmlEscape(r.current.violation),
      r.design.violation.empty() ? "yes" : HtmlEscape(r.design.violation));
  row("amplitude scale", Fmt(r.current.scale), Fmt(r.design.scale));
  for (size_t i = 0; i < r.actuators.size(); ++i) {
    row("peak |u - centre| of " + HtmlEscape(r.actuators[i]) + " (limit " +
            Fmt(r.amplitude[static_cast<Eigen::Index>(i)]) + ")",
        Fmt(r.current.margins.peak[i]), Fmt(r.design.margins.peak[i]));
  }
  for (size_t j = 0; j < r.design.margins.joints.size(); ++j) {
    row("range margin of " + HtmlEscape(r.design.margins.joints[j].name),
        Fmt(r.current.margins.joints[j].margin), Fmt(r.design.margins.joints[j].margin));
  }
  row("largest joint speed",
      Fmt(r.current.margins.max_joint_speed) + " (" + HtmlEscape(r.current.margins.fastest_joint) +
          ")",
      Fmt(r.design.margins.max_joint_speed) + " (" + HtmlEscape(r.design.margins.fastest_joint) +
          ")");
  row("steps with contact", std::to_string(r.current.margins.steps_with_contact),
      std::to_string(r.design.margins.steps_with_contact));
  h << "</table>\n";
}

}  // namespace

std::string DesignPage(const design::DesignResult& r, const std::string& experiment) {
  std::ostringstream h;
  h << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n<title>mjsysid "
       "design: "
    << HtmlEscape(r.model_name) << "</title>\n<style>" << PageCss() << kDesignCss << "</style>\n"
    << InteractiveHead() << "</head><body>\n<h1>Excitation design: " << HtmlEscape(r.model_name)
    << "</h1>\n<table class=\"facts\">\n<tr><td>experiment</td><td>" << HtmlEscape(experiment)
    << "</td></tr>\n<tr><td>criterion</td><td>" << design::CriterionName(r.options.criterion)
    << "</td></tr>\n<tr><td>horizon</td><td>" << r.steps << " steps of " << Fmt(r.timestep, 6)
    << " s (" << Fmt((r.steps - 1) * r.timestep, 6) << " s)</td></tr>\n<tr><td>search</td><td>"
    << r.evaluations << " candidates (" << r.feasible << " met the constraints) in "
    << Fmt(r.seconds) << " s, seed " << r.options.seed << "</td></tr>\n<tr><td>information "
    << "at</td><td>" << (r.options.at_truth ? "simulate.truth" : "the initial values")
    << "</td></tr>\n</table>\n";
  StdSection(h, r);

  // the controls and the predicted motion, on one time axis
  ChartIds ids(PointsPerLine(2 * static_cast<int>(r.actuators.size() + r.joints.size())));
  const std::string group = ids.NextGroup();
  Eigen::VectorXd t(r.steps);
  for (int k = 0; k < r.steps; ++k) t[k] = k * r.timestep;
  h << "<h2>Controls</h2>\n<p class=\"chart-help\">Drag to zoom (every chart follows), "
       "double-click to zoom out; shaded: the amplitude allowed.</p>\n";
  for (size_t i = 0; i < r.actuators.size(); ++i) {
    const auto k = static_cast<Eigen::Index>(i);
    h << Pair("controls", HtmlEscape(r.actuators[i]), t, r.current.ctrl.col(k),
              r.design.ctrl.col(k), r.centre[k] - r.amplitude[k], r.centre[k] + r.amplitude[k],
              group, ids);
  }
  h << "<h2>Predicted motion</h2>\n<p class=\"chart-help\">joint positions simulated at the "
       "parameter values of the information; shaded: the range allowed (limited joints).</p>\n";
  for (const design::DesignResult::JointColumn& j : r.joints) {
    const Eigen::VectorXd cur = r.current.motion.states.col(j.qpos).head(r.steps);
    const Eigen::VectorXd des = r.design.motion.states.col(j.qpos).head(r.steps);
    h << Pair("motion", HtmlEscape(j.name), t, cur, des, j.limited ? j.lower : NAN,
              j.limited ? j.upper : NAN, group, ids);
  }
  ConstraintSection(h, r);
  h << "</body></html>\n";
  return h.str();
}

std::string WriteDesignPage(const design::DesignResult& r, const std::string& experiment,
                            const std::string& dir) {
  const std::string path = (std::filesystem::path(dir) / "design.html").string();
  io::WriteFileAtomically(path, DesignPage(r, experiment));
  return path;
}

}  // namespace mjsysid::report

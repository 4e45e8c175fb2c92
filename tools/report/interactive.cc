#include "tools/report/interactive.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "sysid/assess/residual_diagnostics.h"
#include "tools/report/axes.h"
#include "tools/report/page.h"
#include "tools/report/plots.h"
#include "tools/report/vendor_files.h"

namespace mjsysid::report {
namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

// the layout of the charts and their captions
constexpr char kChartCss[] = R"css(
.chart-row{display:grid;grid-template-columns:3fr 2fr;gap:14px;margin:8px 0}
.chart-row.even{grid-template-columns:1fr 1fr}
.chart{min-width:0}
.chart-title{font-size:13px;font-weight:600}
.chart-title .muted{font-weight:400}
.chart-legend{font-size:12px;min-height:18px;color:#444}
.chart-plot{width:100%;height:210px}
p.chart-help{font-size:13px}
)css";

// The page's glue: a chart from its spec (see ChartHtml), registered in mjsysidCharts and in its
// group, whose members share the time axis (a zoom or pan of one is applied to the others; a
// double-click resets them all).
constexpr char kGlue[] = R"js(
var mjsysidCharts = [];
var mjsysidGroups = {};
var mjsysidSyncing = false;
function mjsysidSync(chart) {
  if (mjsysidSyncing || !chart.mjsysidGroup) return;
  mjsysidSyncing = true;
  var range = chart.isZoomed('x') ? chart.xAxisRange() : null;
  mjsysidGroups[chart.mjsysidGroup].forEach(function (other) {
    if (other !== chart) other.updateOptions({dateWindow: range});
  });
  mjsysidSyncing = false;
}
function mjsysidChart(id, spec) {
  var series = {};
  spec.labels.slice(1).forEach(function (name, i) {
    series[name] = {color: spec.colors[i], strokeWidth: spec.widths[i],
                    strokePattern: spec.dashed[i] ? [6, 3] : null, stepPlot: spec.steps[i]};
  });
  var number = function (v) { return Number(v.toPrecision(5)).toString(); };
  var g = new Dygraph(document.getElementById(id), spec.rows, {
    labels: spec.labels, series: series, xlabel: spec.xlabel, ylabel: spec.ylabel,
    labelsDiv: document.getElementById(id + '-legend'), legend: 'always',
    drawPoints: spec.points, pointSize: 2, axisLabelFontSize: 11, xLabelHeight: 14,
    yLabelWidth: 14, animatedZooms: false,
    axes: {x: {valueFormatter: number}, y: {valueFormatter: number}},
    underlayCallback: spec.band ? function (ctx, area, chart) {
      var top = chart.toDomYCoord(spec.band[1]), bottom = chart.toDomYCoord(spec.band[0]);
      ctx.fillStyle = spec.band_color;
      ctx.fillRect(area.x, top, area.w, bottom - top);
    } : null,
    drawCallback: function (chart, initial) { if (!initial) mjsysidSync(chart); }
  });
  g.mjsysidGroup = spec.group;
  g.mjsysidKind = spec.kind;
  mjsysidCharts.push(g);
  if (spec.group) (mjsysidGroups[spec.group] = mjsysidGroups[spec.group] || []).push(g);
}
)js";

// a colour for css
std::string Css(Rgb c) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "rgb(%d,%d,%d)", c.r, c.g, c.b);
  return buf;
}

// the inputs' colours, one per actuator in turn
constexpr Rgb kInputColors[] = {{31, 119, 180},  {255, 127, 14}, {44, 160, 44},   {214, 39, 40},
                                {148, 103, 189}, {140, 86, 75},  {227, 119, 194}, {127, 127, 127},
                                {188, 189, 34},  {23, 190, 207}};

// v to 6 significant digits (NaN and infinities as they are: JSON null)
double Round6(double v) {
  if (!std::isfinite(v)) return v;
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return std::strtod(buf, nullptr);
}

// the diagnostics of a channel, nullptr when there are none
const ResidualDiagnostics* DiagnosticsOf(const std::vector<ResidualDiagnostics>& all,
                                         const std::string& channel) {
  for (const ResidualDiagnostics& d : all) {
    if (d.channel == channel) return &d;
  }
  return nullptr;
}

// the residual chart's caption: the channel's diagnostics in one line
std::string ResidualCaption(const std::string& label, const ResidualDiagnostics* d,
                            bool segmented) {
  std::string t = HtmlEscape(label) +
                  " residual <span class=\"muted\">(simulated &minus; measured" +
                  std::string(segmented ? ", segment by segment" : "") + ")</span>";
  if (d == nullptr) return t;
  t += "<br><span class=\"muted\">rms " + HtmlEscape(Num(d->rms, 3));
  if (std::isfinite(d->ratio)) {
    t += " = " + HtmlEscape(Num(d->ratio, 3)) + " &sigma;" +
         (d->sigma_from_log ? " (&sigma; from the log)" : "");
  }
  if (std::isfinite(d->lag1)) t += ", lag-1 " + HtmlEscape(Num(d->lag1, 2));
  if (std::isfinite(d->tau)) t += ", correlation " + HtmlEscape(Num(d->tau, 3)) + " samples";
  t += std::string(", ") + (d->white ? "white" : "<b>not white</b>");
  if (std::isfinite(d->portmanteau_p)) t += " (p " + HtmlEscape(Num(d->portmanteau_p, 2)) + ")";
  return t + "</span>";
}

}  // namespace

std::string ChartHtml(const Chart& c, ChartIds& ids) {
  if (c.x.size() == 0 || c.lines.empty()) return "";
  // the rows: the union of the lines' decimated samples
  std::vector<Eigen::Index> rows;
  for (const Line& l : c.lines) {
    const std::vector<Eigen::Index> kept = Decimate(l.y, ids.points);
    rows.insert(rows.end(), kept.begin(), kept.end());
  }
  std::sort(rows.begin(), rows.end());
  rows.erase(std::unique(rows.begin(), rows.end()), rows.end());
  nlohmann::json data = nlohmann::json::array();
  for (const Eigen::Index k : rows) {
    nlohmann::json row = nlohmann::json::array({Round6(c.x[k])});
    for (const Line& l : c.lines) row.push_back(Round6(l.y[k]));
    data.push_back(std::move(row));
  }
  nlohmann::json spec;
  spec["kind"] = c.kind;
  spec["group"] = c.group;
  spec["xlabel"] = c.xlabel;
  spec["ylabel"] = c.ylabel;
  spec["points"] = c.points;
  spec["labels"] = nlohmann::json::array({c.xlabel});
  for (const Line& l : c.lines) {
    spec["labels"].push_back(l.label);
    spec["colors"].push_back(Css(l.color));
    spec["widths"].push_back(l.width);
    spec["dashed"].push_back(l.dashed);
    spec["steps"].push_back(l.step);
  }
  if (std::isfinite(c.band_lo) && std::isfinite(c.band_hi)) {
    spec["band"] = {c.band_lo, c.band_hi};
    spec["band_color"] = c.band_color;
  }
  spec["rows"] = std::move(data);
  // "</" never closes the script early: JSON allows "<\/"
  std::string json = spec.dump();
  for (size_t at = json.find("</"); at != std::string::npos; at = json.find("</", at + 3)) {
    json.replace(at, 2, "<\\/");
  }
  const std::string id = ids.Next();
  std::ostringstream h;
  h << "<div class=\"chart " << c.kind << "\"><div class=\"chart-title\">" << c.title
    << "</div><div class=\"chart-legend\" id=\"" << id
    << "-legend\"></div><div class=\"chart-plot\" "
    << "id=\"" << id << "\"></div></div>\n<script>mjsysidChart(\"" << id << "\", " << json
    << ");</script>\n";
  return h.str();
}

int PointsPerLine(int columns) {
  return std::clamp(kPageLinePoints / std::max(1, 4 * columns), kMinLinePoints, kInteractivePoints);
}

std::string InteractiveHead() {
  // the library's files without their source-map comments (the maps are not shipped)
  auto without_map = [](std::string_view text) {
    const size_t at = text.rfind("sourceMappingURL=");
    if (at == std::string_view::npos) return std::string(text);
    const size_t line = text.rfind('\n', at);
    return std::string(text.substr(0, line == std::string_view::npos ? 0 : line + 1));
  };
  return "<style>" + without_map(DygraphCss()) + kChartCss + "</style>\n<script>" +
         without_map(DygraphJs()) + "</script>\n<script>" + kGlue + "</script>\n";
}

std::string SequenceCharts(const SequenceResult& sequence,
                           const std::vector<ResidualDiagnostics>& diagnostics,
                           const LoggedInputs& inputs, ChartIds& ids) {
  const SequenceResult s = WithStateColumns(sequence);  // fitted states as sensors
  const Eigen::Index samples = s.time.size();
  const std::string group = ids.NextGroup();
  std::ostringstream h;
  const bool segmented = s.simulated_one_piece.rows() == samples && samples > 0;
  const RowMatrix& fitted = segmented ? s.simulated_one_piece : s.simulated_final;
  const std::vector<std::string> labels = ColumnLabels(s);
  for (Eigen::Index j = 0; j < s.measured.cols(); ++j) {
    const std::string& label = labels[static_cast<size_t>(j)];
    auto column = [&](const RowMatrix& m) {
      return m.rows() == samples && m.cols() > j ? Eigen::VectorXd(m.col(j))
                                                 : Eigen::VectorXd::Constant(samples, kNan);
    };
    // the signals
    Chart signal;
    signal.kind = "signal";
    signal.group = group;
    signal.xlabel = "time (s)";
    signal.x = s.time;
    signal.title = HtmlEscape(label);
    if (static_cast<size_t>(j) < s.channel_fits.size()) {
      const ChannelFit& f = s.channel_fits[static_cast<size_t>(j)];
      if (std::isfinite(f.fit_initial) && std::isfinite(f.fit_final)) {
        signal.title += " <span class=\"muted\">% fit " + HtmlEscape(Num(f.fit_initial, 3)) +
                        " &rarr; " + HtmlEscape(Num(f.fit_final, 3)) + "</span>";
      }
    }
    signal.lines.push_back({"measured", column(s.measured), kMeasured, 2.5, false, false});
    signal.lines.push_back({"initial", column(s.simulated_initial), kBefore, 1.2, true, false});
    if (segmented) {
      signal.lines.push_back({"segments", column(s.simulated_final), kSegments, 1.2, true, false});
    }
    signal.lines.push_back({"estimate", column(fitted), kAfter, 1.4, false, false});

    // the residual at the estimate, with its band of +-2 sigma
    Chart residual;
    residual.kind = "residual";
    residual.group = group;
    residual.xlabel = "time (s)";
    residual.x = s.time;
    const ResidualDiagnostics* d = DiagnosticsOf(diagnostics, label);
    residual.title = ResidualCaption(label, d, segmented);
    residual.lines.push_back(
        {"residual", column(s.simulated_final) - column(s.measured), kInk, 1.0, false, false});
    if (d != nullptr && std::isfinite(d->sigma) && d->sigma > 0) {
      residual.band_lo = -2 * d->sigma;
      residual.band_hi = 2 * d->sigma;
    }
    h << "<div class=\"chart-row\">\n"
      << ChartHtml(signal, ids) << ChartHtml(residual, ids) << "</div>\n";
  }
  // the logged inputs
  if (inputs.ctrl.rows() > 0) {
    Chart in;
    in.kind = "inputs";
    in.group = group;
    in.xlabel = "time (s)";
    in.x = inputs.time;
    in.title = "inputs <span class=\"muted\">(the logged controls at their own times)</span>";
    for (Eigen::Index a = 0; a < inputs.ctrl.cols(); ++a) {
      const auto i = static_cast<size_t>(a);
      in.lines.push_back({i < inputs.names.size() ? inputs.names[i] : "ctrl " + std::to_string(a),
                          inputs.ctrl.col(a), kInputColors[i % std::size(kInputColors)], 1.3, false,
                          i < inputs.held.size() && inputs.held[i]});
    }
    h << ChartHtml(in, ids);
  }
  return h.str();
}

std::string AutocorrelationCharts(const std::vector<SequenceResult>& fitted,
                                  const std::vector<ResidualDiagnostics>& diagnostics,
                                  ChartIds& ids) {
  std::ostringstream h;
  int row = 0;  // two charts per row
  for (const ChannelResiduals& c : PoolResidualsByChannel(fitted)) {
    Eigen::Index longest = 0, measured = 0;
    for (const Eigen::VectorXd& e : c.columns) {
      longest = std::max(longest, e.size());
      measured += (e.array() == e.array()).count();  // not NaN
    }
    if (measured < 2) continue;
    const int lags = static_cast<int>(
        std::min<Eigen::Index>(kAutocorrelationLags, std::max<Eigen::Index>(1, longest / 4)));
    Chart acf;
    acf.kind = "autocorrelation";
    acf.xlabel = "lag (samples)";
    acf.x = Eigen::VectorXd::LinSpaced(lags + 1, 0, lags);
    acf.points = true;
    const ResidualDiagnostics* d = DiagnosticsOf(diagnostics, c.channel);
    acf.title = HtmlEscape(c.channel) + " <span class=\"muted\">autocorrelation of the residual" +
                (d != nullptr && std::isfinite(d->tau)
                     ? ", correlation time " + HtmlEscape(Num(d->tau, 3)) + " samples"
                     : std::string()) +
                "</span>";
    acf.lines.push_back(
        {"autocorrelation", ResidualAutocorrelation(c.columns, lags), kBefore, 1.2, false, false});
    const double band = 1.96 / std::sqrt(static_cast<double>(measured));
    acf.band_lo = -band;
    acf.band_hi = band;
    acf.band_color = "rgba(31,95,191,0.13)";
    h << (row % 2 == 0 ? "<div class=\"chart-row even\">\n" : "") << ChartHtml(acf, ids)
      << (row % 2 == 1 ? "</div>\n" : "");
    ++row;
  }
  if (row % 2 == 1) h << "</div>\n";
  return h.str();
}

}  // namespace mjsysid::report

#include "tools/report/page.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "sysid/io/warnings.h"
#include "tools/report/axes.h"
#include "tools/report/canvas.h"
#include "tools/report/correlation.h"
#include "tools/report/interactive.h"
#include "tools/report/plots.h"
#include "tools/report/report.h"

namespace mjsysid::report {

// text for html: & < > " ' escaped
std::string HtmlEscape(const std::string& s) {
  std::string out;
  for (const char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

// standard base64 with padding (RFC 4648), for data URIs
std::string Base64(const std::string& bytes) {
  static constexpr char kAlphabet[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (size_t i = 0; i < bytes.size(); i += 3) {
    uint32_t v = static_cast<uint8_t>(bytes[i]) << 16;
    if (i + 1 < bytes.size()) v |= static_cast<uint8_t>(bytes[i + 1]) << 8;
    if (i + 2 < bytes.size()) v |= static_cast<uint8_t>(bytes[i + 2]);
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? kAlphabet[(v >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? kAlphabet[v & 63] : '=';
  }
  return out;
}

namespace {

using io::FitResultFile;
using mjsysid::ParameterEstimate;

// the css class of a status badge
std::string StatusClass(const std::string& status) {
  std::string s = status;
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char ch) { return std::tolower(ch); });
  if (s.find("fail") != std::string::npos || s.find("error") != std::string::npos ||
      s.find("diverg") != std::string::npos) {
    return "bad";
  }
  if (s == FitStatusName(FitStatus::kConverged) || s == "success" || s == "succeeded" ||
      s == "ok" || s == "done") {
    return "ok";
  }
  return "warn";
}

// a number for the page: 6 digits, infinity as the sign
std::string HtmlNum(double v, int digits = 6) {
  if (std::isinf(v)) return v > 0 ? "\xE2\x88\x9E" : "\xE2\x88\x92\xE2\x88\x9E";
  return HtmlEscape(Num(v, digits));
}

constexpr char kCss[] = R"css(
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,Helvetica,Arial,sans-serif;color:#222;
  max-width:1240px;margin:24px auto;padding:0 16px;line-height:1.4}
h1{font-size:26px;margin:0 0 6px}
h2{font-size:20px;margin:32px 0 10px;padding-bottom:4px;border-bottom:1px solid #ddd}
h3{font-size:16px;margin:20px 0 6px}
.badge{display:inline-block;padding:1px 10px;border-radius:10px;color:#fff;font-weight:600}
.ok{background:#2e7d32}.warn{background:#ef6c00}.bad{background:#c62828}
.muted{color:#777}
table{border-collapse:collapse;font-size:14px;margin:4px 0}
th,td{padding:4px 10px;border-bottom:1px solid #eee;text-align:left;vertical-align:top}
th{background:#f6f6f6}
td.n{text-align:right;font-family:ui-monospace,Menlo,Consolas,monospace;white-space:nowrap}
table.facts td:first-child{color:#666}
tr.unid td{background:#fde8e8}
tr.val td{background:#eef4fb}
tr.best td{font-weight:600}
.flag{display:inline-block;padding:0 6px;margin:0 4px 2px 0;border-radius:4px;font-size:12px;
  background:#e8e8e8}
.flag.unid{background:#c62828;color:#fff}
ul.warnings li{color:#8a4b00}
svg,img{max-width:100%;height:auto;border:1px solid #eee;background:#fff}
details.still summary{cursor:pointer;color:#555;font-size:13px;margin:4px 0 12px}
table.correlation td.n{text-align:center;min-width:34px;font-size:12px}
)css";

// the parameter table, with the unidentifiable combinations below it
void ParameterSection(std::ostringstream& h, const FitResultFile& r) {
  h << "<h2>Parameters</h2>\n";
  if (r.parameters.empty()) {
    h << "<p class=\"muted\">no parameters</p>\n";
  } else {
    h << "<table class=\"params\">\n<tr><th>parameter</th><th>initial</th><th>value</th>"
         "<th>std</th><th>rel. std</th><th>95% CI</th><th>truth</th><th>truth in CI</th>"
         "<th>flags</th></tr>\n";
    for (const ParameterEstimate& p : r.parameters) {
      h << "<tr" << (p.identifiable ? "" : " class=\"unid\"") << "><td>" << HtmlEscape(p.name)
        << "</td><td class=\"n\">" << HtmlNum(p.initial) << "</td><td class=\"n\"><b>"
        << HtmlNum(p.value) << "</b></td><td class=\"n\">" << HtmlNum(p.std_error, 3)
        << "</td><td class=\"n\">"
        << (std::isinf(p.std_error) ? HtmlNum(p.std_error)
            : p.value != 0          ? HtmlNum(100 * p.std_error / std::abs(p.value), 3) + " %"
                                    : "&ndash;")
        << "</td><td class=\"n\">[" << HtmlNum(p.ci95_low) << ", " << HtmlNum(p.ci95_high)
        << "]</td><td class=\"n\">" << (p.truth ? HtmlNum(*p.truth) : "&ndash;") << "</td><td>";
      if (p.truth) h << (*p.truth >= p.ci95_low && *p.truth <= p.ci95_high ? "yes" : "<b>no</b>");
      h << "</td><td>";
      if (p.at_lower) h << "<span class=\"flag\">at lower bound</span>";
      if (p.at_upper) h << "<span class=\"flag\">at upper bound</span>";
      if (!p.identifiable) h << "<span class=\"flag unid\">unidentifiable</span>";
      h << "</td></tr>\n";
    }
    h << "</table>\n";
  }
  // quantities derived from the estimate (body_inertial: mass, centre of mass, principal moments)
  if (!r.derived.empty()) {
    h << "<h3>Derived quantities</h3>\n<table class=\"derived\">\n<tr><th>quantity</th>"
         "<th>unit</th><th>value</th><th>std</th><th>95% CI</th><th>truth</th><th>from</th>"
         "</tr>\n";
    for (const DerivedQuantity& d : r.derived) {
      h << "<tr><td>" << HtmlEscape(d.name) << "</td><td>" << HtmlEscape(d.unit)
        << "</td><td class=\"n\"><b>" << HtmlNum(d.value) << "</b></td><td class=\"n\">"
        << HtmlNum(d.std_error, 3) << "</td><td class=\"n\">[" << HtmlNum(d.ci95_low) << ", "
        << HtmlNum(d.ci95_high) << "]</td><td class=\"n\">"
        << (d.truth ? HtmlNum(*d.truth) : "&ndash;") << "</td><td>" << HtmlEscape(d.derived_from)
        << "</td></tr>\n";
    }
    h << "</table>\n";
  }
  h << "<h3>Unidentifiable combinations</h3>\n";
  if (r.uncertainty.unidentifiable.empty()) {
    h << "<p class=\"muted\">none: the data determine every parameter</p>\n";
  } else {
    h << "<ul>\n";
    for (const std::string& u : r.uncertainty.unidentifiable)
      h << "<li>" << HtmlEscape(u) << "</li>\n";
    h << "</ul>\n";
  }
}

// a % fit or an NRMSE cell; NaN (a constant channel, a failed simulation) as a dash
std::string MetricCell(double v, const char* unit) {
  if (!std::isfinite(v)) return "<td class=\"n\">&ndash;</td>";
  return "<td class=\"n\">" + HtmlEscape(Num(v, 3)) + unit + "</td>";
}

// per sequence and channel: % fit and NRMSE at the start and at the estimate, fitted sequences
// first, then the held-out ones
void FitQualitySection(std::ostringstream& h, const FitResultFile& r) {
  h << "<h2>Fit quality</h2>\n<p class=\"muted\">per channel: % fit = 100 (1 &minus; NRMSE), "
       "NRMSE = RMS(simulated &minus; measured) / std(measured); 100 % is exact, 0 % no better "
       "than the measured mean. Validation sequences are held out: simulated, not fitted.</p>\n";
  if (r.sequences.empty() && r.validation.empty()) {
    h << "<p class=\"muted\">no sequences recorded</p>\n";
    return;
  }
  bool segmented = false;  // a fit in segments: the segments' % fit in a column of its own
  for (const SequenceResult& s : r.sequences)
    segmented = segmented || s.simulated_one_piece.rows() > 0;
  if (segmented) {
    h << "<p>Fitted in segments: <em>estimate</em> is the estimate simulated in one piece from "
         "each sequence's first state (what the identified model gives); <em>segments</em> is "
         "each segment simulated from its own fitted state (what the fit fitted).</p>\n";
  }
  h << "<table class=\"metrics\">\n<tr><th>sequence</th><th>role</th><th>channel</th>"
       "<th>% fit, start</th><th>% fit, estimate</th>"
    << (segmented ? "<th>% fit, segments</th>" : "")
    << "<th>NRMSE, start</th><th>NRMSE, estimate</th></tr>\n";
  for (const std::vector<SequenceResult>* list : {&r.sequences, &r.validation}) {
    const bool held_out = list == &r.validation;
    for (const SequenceResult& s : *list) {
      for (const ChannelFit& f : s.channel_fits) {
        h << "<tr" << (held_out ? " class=\"val\"" : "") << "><td>" << HtmlEscape(s.name)
          << "</td><td>" << (held_out ? "validation (not fitted)" : "fit") << "</td><td>"
          << HtmlEscape(f.channel) << "</td>" << MetricCell(f.fit_initial, " %")
          << MetricCell(f.fit_final, " %")
          << (segmented ? MetricCell(f.fit_segments, " %") : std::string())
          << MetricCell(f.nrmse_initial, "") << MetricCell(f.nrmse_final, "") << "</tr>\n";
      }
    }
  }
  h << "</table>\n";
}

// per fitted channel: the residuals' bias, size against sigma, whiteness and correlation time
// (sysid/assess/residual_diagnostics.h), non-white rows marked; what the intervals came from
void ResidualSection(std::ostringstream& h, const FitResultFile& r, ChartIds& ids) {
  if (r.residuals.empty()) return;
  h << "<h2>Residuals</h2>\n<p class=\"muted\">simulated &minus; measured at the estimate, per "
       "channel over the fitted sequences. White noise has no correlation beyond chance "
       "(Ljung-Box test over 20 lags) and a correlation time of about 1 sample; residuals that "
       "carry model error, filtering or stamp jitter are correlated over many samples, and the "
       "data then hold fewer independent samples than rows. Bias in standard errors of a mean "
       "of such residuals (above 4: an offset the model lacks).</p>\n";
  h << "<p>intervals from "
    << HtmlEscape(r.intervals_from.empty() ? "white residuals" : r.intervals_from) << "</p>\n";
  h << "<table class=\"residuals\">\n<tr><th>channel</th><th>samples</th><th>mean</th>"
       "<th>rms</th><th>rms / sigma</th><th>bias / se</th><th>lag-1</th>"
       "<th>correlation (samples)</th><th>white</th></tr>\n";
  for (const ResidualDiagnostics& d : r.residuals) {
    h << "<tr" << (d.white ? "" : " class=\"unid\"") << "><td>" << HtmlEscape(d.channel)
      << "</td><td class=\"n\">" << d.samples << "</td>" << MetricCell(d.mean, "")
      << MetricCell(d.rms, "") << MetricCell(d.ratio, "") << MetricCell(d.bias_units, "")
      << MetricCell(d.lag1, "") << MetricCell(d.tau, "") << "<td>"
      << (d.white ? "yes" : "<b>no</b>") << "</td></tr>\n";
  }
  h << "</table>\n";
  const std::string acf = AutocorrelationCharts(r.sequences, r.residuals, ids);
  if (!acf.empty()) {
    h << "<h3>Autocorrelation of the residuals</h3>\n<p class=\"muted chart-help\">per channel "
         "over the fitted sequences; white noise stays inside the shaded band (&plusmn;1.96 / "
         "&radic;n) at 95 % of the lags, residuals that carry model error decay slowly. Drag to "
         "zoom, double-click to zoom out.</p>\n"
      << acf;
  }
}

// multi-start: every start (status, costs, start and estimate per parameter, the best marked) and
// the spread per parameter; the local-minimum warning is among the warnings
void StartsSection(std::ostringstream& h, const FitResultFile& r) {
  if (r.starts.size() < 2) return;
  h << "<h2>Starts</h2>\n<p class=\"muted\">" << r.starts.size()
    << " fits from starts spread in the bounds (start 0: the experiment's own); the result is "
       "start "
    << r.best_start
    << "'s: the lowest final cost of the fits that converged (status converged or "
       "model_mismatch), else of all; a start that ended in another minimum (its cost above the "
       "best's by more than the noise explains, with other estimates) is marked "
       "local_minimum</p>\n";
  h << "<table class=\"starts\">\n<tr><th>start</th><th>status</th><th>iterations</th>"
       "<th>initial cost</th><th>final cost</th>";
  for (const ParameterEstimate& p : r.parameters) {
    h << "<th>" << HtmlEscape(p.name) << "<br><span class=\"muted\">start &rarr; estimate</span>"
      << "</th>";
  }
  h << "</tr>\n";
  for (size_t k = 0; k < r.starts.size(); ++k) {
    const StartResult& st = r.starts[k];
    const bool best = static_cast<int>(k) == r.best_start;
    h << "<tr" << (best ? " class=\"best\"" : "") << "><td>" << k << (best ? " (best)" : "")
      << "</td><td>"
      << (st.error.empty() ? HtmlEscape(FitStatusName(st.status))
                           : "failed: " + HtmlEscape(st.error))
      << "</td><td class=\"n\">" << st.iterations << "</td><td class=\"n\">"
      << HtmlNum(st.initial_cost) << "</td><td class=\"n\">" << HtmlNum(st.final_cost) << "</td>";
    for (Eigen::Index j = 0; j < static_cast<Eigen::Index>(r.parameters.size()); ++j) {
      h << "<td class=\"n\">" << (j < st.start.size() ? HtmlNum(st.start[j], 4) : "&ndash;")
        << " &rarr; " << (j < st.estimate.size() ? HtmlNum(st.estimate[j], 6) : "&ndash;")
        << "</td>";
    }
    h << "</tr>\n";
  }
  h << "</table>\n<h3>Spread of the estimates over the starts</h3>\n<table class=\"spread\">\n"
       "<tr><th>parameter</th><th>min</th><th>max</th><th>(max &minus; min) / |estimate|</th>"
       "</tr>\n";
  for (const ParameterSpread& sp : r.start_spread) {
    h << "<tr><td>" << HtmlEscape(sp.name) << "</td><td class=\"n\">" << HtmlNum(sp.min)
      << "</td><td class=\"n\">" << HtmlNum(sp.max) << "</td><td class=\"n\">"
      << HtmlNum(sp.relative, 3) << "</td></tr>\n";
  }
  h << "</table>\n";
}

// how many of `count` sequences have no plot (an empty PNG), when any: the plots are capped
// (report.h, PlottedSequences), every sequence is in the fit quality table
void PlotsLeftOut(std::ostringstream& h, size_t count, const std::vector<std::string>& pngs) {
  size_t plotted = 0;
  for (size_t i = 0; i < count && i < pngs.size(); ++i) plotted += !pngs[i].empty();
  if (plotted == count) return;
  h << "<p class=\"muted plots-left-out\">" << plotted << " of " << count
    << " sequences plotted: the first " << kPlotFirst << " and the " << kPlotWorst
    << " others with the lowest % fit at the estimate; " << count - plotted
    << " plots left out (every sequence's % fit and NRMSE are in the fit quality table "
       "above)</p>\n";
}

// one plotted sequence: its heading, the interactive charts (interactive.h), and the still plot
// (its PNG) folded below them
void SequenceBlock(std::ostringstream& h, const SequenceResult& s,
                   const std::vector<ResidualDiagnostics>& diagnostics,
                   const LoggedExperiment* logged, const std::string& png, bool held_out,
                   ChartIds& ids) {
  h << "<h3>" << HtmlEscape(s.name)
    << (held_out ? " <span class=\"muted\">validation (not fitted)</span>" : "") << "</h3>\n";
  h << SequenceCharts(s, diagnostics,
                      logged != nullptr ? InputsOf(*logged, s.name) : LoggedInputs(), ids);
  h << "<details class=\"still\"><summary>the same as a still image</summary><img alt=\""
    << (held_out ? "validation sequence " : "sequence ") << HtmlEscape(s.name)
    << "\" src=\"data:image/png;base64," << Base64(png) << "\"></details>\n";
}

}  // namespace

const char* PageCss() { return kCss; }

std::string Page(const FitResultFile& r, const std::vector<std::string>& sequence_pngs,
                 const std::vector<std::string>& validation_pngs, const std::string& motion_html,
                 const LoggedExperiment* logged) {
  std::ostringstream h;
  // the plotted columns of the page set how many samples each chart line keeps
  int columns = 0;
  for (const auto& [list, pngs] :
       {std::pair(&r.sequences, &sequence_pngs), std::pair(&r.validation, &validation_pngs)}) {
    for (size_t i = 0; i < list->size() && i < pngs->size(); ++i) {
      if (!(*pngs)[i].empty()) {
        const SequenceResult& s = (*list)[i];
        columns += static_cast<int>(s.measured.cols() + s.state_measured.cols());
      }
    }
  }
  ChartIds ids(PointsPerLine(columns));
  const std::string name = r.name.empty() ? "(unnamed)" : r.name;
  h << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
    << "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
    << "<title>mjsysid report: " << HtmlEscape(name) << "</title>\n<style>" << kCss << "</style>\n"
    << InteractiveHead() << "</head>\n<body>\n";

  // header
  h << "<h1>" << HtmlEscape(name) << "</h1>\n<p><span class=\"badge " << StatusClass(r.status)
    << "\">" << HtmlEscape(r.status.empty() ? "unknown" : r.status) << "</span> "
    << HtmlEscape(TerminationText(r.termination)) << "</p>\n";
  // the intervals mean something only for a converged fit (FitStatus, sysid/types.h)
  if (!r.intervals_valid) {
    h << "<p><span class=\"badge bad\">intervals not valid</span> the fit's status is "
      << HtmlEscape(r.status.empty() ? "unknown" : r.status)
      << ": the standard errors and 95% intervals below do not describe the estimate (see the "
         "warnings)</p>\n";
  }

  // facts
  const double ratio =
      r.initial_cost != 0 ? r.final_cost / r.initial_cost : std::numeric_limits<double>::infinity();
  const std::pair<std::string, std::string> facts[] = {
      {"experiment", HtmlEscape(r.experiment)},
      {"created", HtmlEscape(r.created)},
      {"iterations", std::to_string(r.iterations)},
      {"initial cost", HtmlNum(r.initial_cost)},
      {"final cost", HtmlNum(r.final_cost) + " <span class=\"muted\">(" + HtmlNum(ratio, 3) +
                         " of the initial)</span>"},
      {"residual variance", HtmlNum(r.uncertainty.residual_variance)},
      {"residuals", std::to_string(r.num_residuals)},
      {"wall time", HtmlNum(r.seconds, 4) + " s"},
      {"jacobian", HtmlEscape(r.diagnostics.jacobian_mode)},
      {"versions",
       "mjsysid " + HtmlEscape(r.mjsysid_version) + ", MuJoCo " + HtmlEscape(r.mujoco_version)}};
  h << "<table class=\"facts\">\n";
  for (const auto& [key, value] : facts)
    h << "<tr><td>" << key << "</td><td>" << value << "</td></tr>\n";
  for (const auto& [model, file] : r.identified_models) {
    h << "<tr><td>identified model</td><td>" << HtmlEscape(model) << ": " << HtmlEscape(file)
      << "</td></tr>\n";
  }
  h << "</table>\n";

  ParameterSection(h, r);
  h << CorrelationSection(r);
  StartsSection(h, r);

  // warnings
  h << "<h2>Warnings</h2>\n";
  if (r.warnings.empty()) {
    h << "<p class=\"muted\">none</p>\n";
  } else {
    h << "<ul class=\"warnings\">\n";
    for (const std::string& w : io::GroupedWarningLines(r.warnings))
      h << "<li>" << HtmlEscape(w) << "</li>\n";
    h << "</ul>\n";
  }

  // plots: cost and parameters as svg, sequences as png
  h << "<h2>Cost</h2>\n";
  const Figure cost = CostFigure(r), params = ParametersFigure(r);
  h << RenderSvg(cost.width, cost.height, "cost", cost.draw);
  h << "<h2>Parameters over the iterations</h2>\n";
  h << RenderSvg(params.width, params.height, "params", params.draw);
  FitQualitySection(h, r);
  ResidualSection(h, r, ids);
  h << "<h2>Sequences</h2>\n";
  if (r.sequences.empty()) {
    h << "<p class=\"muted\">no sequences recorded</p>\n";
  } else {
    h << "<p class=\"muted chart-help\">per channel, the signals and, beside them, the residual at "
         "the estimate (the shaded band: &plusmn;2 &sigma;); below, the logged inputs. Drag across "
         "a "
         "chart to zoom in (the sequence's charts follow), double-click to zoom out, shift-drag to "
         "pan; the values under the pointer are above each chart.</p>\n";
  }
  if (logged != nullptr && !logged->note.empty() && !r.sequences.empty()) {
    h << "<p class=\"muted\">no input plots: " << HtmlEscape(logged->note) << "</p>\n";
  }
  PlotsLeftOut(h, r.sequences.size(), sequence_pngs);
  for (size_t i = 0; i < r.sequences.size() && i < sequence_pngs.size(); ++i) {
    if (sequence_pngs[i].empty()) continue;  // not plotted
    SequenceBlock(h, r.sequences[i], r.residuals, logged, sequence_pngs[i], false, ids);
  }
  if (!r.validation.empty()) {
    h << "<h2>Validation sequences (not fitted)</h2>\n<p class=\"muted\">held out of the fit "
         "(experiment <code>validation:</code>): simulated from their logged initial state at the "
         "start and at the estimate</p>\n";
  }
  if (!r.validation.empty()) PlotsLeftOut(h, r.validation.size(), validation_pngs);
  for (size_t i = 0; i < r.validation.size() && i < validation_pngs.size(); ++i) {
    if (validation_pngs[i].empty()) continue;  // not plotted
    SequenceBlock(h, r.validation[i], {}, logged, validation_pngs[i], true, ids);
  }
  // the motion section (tools/report/motion.h), when the caller made one
  h << motion_html;
  // solver settings: reference, after the results (the table grows with every option)
  h << "<h2>Solver settings</h2>\n";
  if (r.solver.empty()) {
    h << "<p class=\"muted\">none recorded</p>\n";
  } else {
    h << "<table class=\"facts\">\n";
    for (const auto& [key, value] : r.solver) {
      h << "<tr><td>" << HtmlEscape(key) << "</td><td>" << HtmlEscape(value) << "</td></tr>\n";
    }
    h << "</table>\n";
  }

  h << "<p class=\"muted\">written by mjsysid from result.yaml and result.h5; the plots are also "
       "in this folder as cost.png, parameters.png, seq_*.png"
    << (r.validation.empty() ? "" : " and val_*.png") << "</p>\n</body>\n</html>\n";
  return h.str();
}

}  // namespace mjsysid::report

// The report's HTML page: one self-contained file (inline CSS; the cost and parameter plots as
// inline SVG; the sequence plots as interactive charts, the vendored dygraphs and its data inline
// (tools/report/interactive.h), each with its still plot as a base64 PNG data URI folded below;
// no external resources: it works offline).
//
// Sections, in order: header (name, status badge, termination), facts (experiment, costs,
// iterations, wall time, versions, identified models), parameters (table; unidentifiable rows
// highlighted; the unidentifiable combinations listed), parameter correlation (matrix,
// tools/report/correlation.h), starts (multi-start only: every start's status, costs, start and
// estimate, and the spread), warnings (those that recur per sequence once, sysid/io/warnings.h),
// cost, parameters over the iterations, fit quality (every sequence and channel: % fit and NRMSE
// at the start and at the estimate, sysid/assess/metrics.h; fitted and held-out sequences),
// residuals (diagnostics per channel and their autocorrelation charts), sequences (the plotted
// ones, report.h's PlottedSequences, and how many were left out: signals, residuals and logged
// inputs per sequence), validation sequences (not fitted; likewise), motion (when given: an
// animated WebP data URI), solver settings. Every text from the result is HTML-escaped.
#pragma once

#include <string>
#include <vector>

#include "sysid/io/result.h"
#include "tools/report/logged.h"

namespace mjsysid::report {

// text for html: & < > " ' escaped
std::string HtmlEscape(const std::string& s);
// the pages' style sheet (the fit report's and the design page's)
const char* PageCss();
// standard base64 with padding (RFC 4648), for data URIs
std::string Base64(const std::string& bytes);

// the page; sequence_pngs[i] is the PNG of result.sequences[i], validation_pngs[i] that of
// result.validation[i] ("": not plotted, and the page says how many were left out); motion_html
// (MotionHtml, tools/report/motion.h) goes after the sequences; logged: the experiment loaded
// again, for the input plots (nullptr: none)
std::string Page(const io::FitResultFile& result, const std::vector<std::string>& sequence_pngs,
                 const std::vector<std::string>& validation_pngs = {},
                 const std::string& motion_html = "", const LoggedExperiment* logged = nullptr);

}  // namespace mjsysid::report

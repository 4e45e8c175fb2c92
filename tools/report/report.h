// `sysid report DIR`: a fit's results (DIR/result.yaml + DIR/result.h5) as one self-contained
// HTML page and PNG plots, written into DIR.
//
// Files written (each atomically, by io::WriteFileAtomically):
//   report.html      one page, no external resources (tools/report/page.h lists the sections)
//   cost.png         cost vs iteration, log scale (linear when a cost is <= 0)
//   parameters.png   one panel per parameter: value over the iterations, final value with its 95%
//                    interval as an error bar, truth as a dashed line when known
//   seq_<name>.png   per sequence, one panel per fitted sensor column vs time: measured (grey),
//                    simulated with the initial parameters (blue, dashed), with the fitted ones
//                    (red), each panel labelled with its % fit at both. <name> keeps
//                    [A-Za-z0-9_.-] of the sequence name, '_' for the rest.
//   val_<name>.png   the same for each held-out sequence (experiment `validation:`), headed
//                    "validation (not fitted)"
//                    Only some sequences are plotted (PlottedSequences, below), fitted and held-out
//                    apart: the first kPlotFirst and the kPlotWorst worst by % fit; the page says
//                    how many were left out, and its fit quality table lists every sequence.
//   motion.webp      the initial and fitted simulation of the first sequence side by side, an
//                    animated WebP also embedded in the page (tools/report/motion.h); not written
//                    when there is no clip (the page says why)
// Lines of more than 2000 points are decimated (min and max per bucket, peaks kept). The plots are
// drawn with cairo (tools/report/canvas.h), their text in DejaVu Sans.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include "sysid/io/result.h"
#include "tools/report/motion.h"

namespace mjsysid::report {

// the report could not be written (the results could not be read: io::ResultError)
class ReportError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct ReportOptions {
  MotionOptions motion;  // the motion clip (motion.enabled = false: `--no-video`)
};

// Reads the results with io::ReadResult(dir) and writes the report files into dir. Returns the
// number of files written; `summary` (optional) receives a few lines for the terminal ending in a
// newline (name, status, parameters, the files). Throws io::ResultError when the results cannot
// be read and ReportError when a file cannot be written.
int WriteReport(const std::string& dir, std::string* summary);
int WriteReport(const std::string& dir, const ReportOptions& options, std::string* summary);

// the same for results already in memory (`result` as ReadResult would return it)
int WriteReport(const io::FitResultFile& result, const std::string& dir, std::string* summary);
int WriteReport(const io::FitResultFile& result, const std::string& dir,
                const ReportOptions& options, std::string* summary);

// the sequences plotted (indices into `sequences`, ascending): the first kPlotFirst, then the
// kPlotWorst others with the lowest % fit at the estimate (the mean of their channels' fit_final,
// a channel without one, NaN, left out; a sequence without any is never among the worst)
inline constexpr size_t kPlotFirst = 12, kPlotWorst = 4;
std::vector<size_t> PlottedSequences(const std::vector<SequenceResult>& sequences);

// the pieces, for tests and other front ends
std::string ReportHtml(const io::FitResultFile& result);  // the page, PNGs embedded, no motion
std::string CostPng(const io::FitResultFile& result);
std::string ParametersPng(const io::FitResultFile& result);
std::string SequencePng(const io::FitResultFile& result, const SequenceResult& sequence,
                        bool held_out = false);
// "<prefix><name>.png" (prefix "seq_", or "val_" for held-out sequences), sanitized as above
std::string SequenceFileName(const std::string& sequence_name, const std::string& prefix = "seq_");

}  // namespace mjsysid::report

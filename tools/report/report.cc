#include "tools/report/report.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "sysid/io/atomic_file.h"
#include "tools/report/axes.h"
#include "tools/report/canvas.h"
#include "tools/report/page.h"
#include "tools/report/plots.h"

namespace mjsysid::report {
namespace {

using io::FitResultFile;
using mjsysid::ParameterEstimate;
using mjsysid::SequenceResult;

std::string Png(const Figure& f) { return RenderPng(f.width, f.height, f.draw); }

// the file written atomically; a failure is a ReportError
void WriteFile(const std::string& path, const std::string& bytes) {
  try {
    io::WriteFileAtomically(path, bytes);
  } catch (const io::FileError& e) {
    throw ReportError(e.what());
  }
}

}  // namespace

std::string SequenceFileName(const std::string& sequence_name, const std::string& prefix) {
  std::string name;
  for (const char ch : sequence_name) {
    const auto c = static_cast<unsigned char>(ch);
    name += std::isalnum(c) || c == '_' || c == '.' || c == '-' ? ch : '_';
  }
  return prefix + name + ".png";
}

std::string CostPng(const FitResultFile& result) { return Png(CostFigure(result)); }

std::string ParametersPng(const FitResultFile& result) { return Png(ParametersFigure(result)); }

std::string SequencePng(const FitResultFile&, const SequenceResult& sequence, bool held_out) {
  return Png(SequenceFigure(WithStateColumns(sequence), held_out));  // fitted states as sensors
}

std::vector<size_t> PlottedSequences(const std::vector<SequenceResult>& sequences) {
  std::vector<size_t> plotted;
  for (size_t i = 0; i < sequences.size() && i < kPlotFirst; ++i) plotted.push_back(i);
  // the rest by their mean % fit at the estimate, lowest first
  std::vector<std::pair<double, size_t>> rest;
  for (size_t i = kPlotFirst; i < sequences.size(); ++i) {
    double sum = 0;
    int n = 0;
    for (const ChannelFit& f : sequences[i].channel_fits) {
      if (std::isnan(f.fit_final)) continue;
      sum += f.fit_final;
      ++n;
    }
    if (n > 0) rest.emplace_back(sum / n, i);
  }
  const size_t worst = std::min(rest.size(), kPlotWorst);
  std::partial_sort(rest.begin(), rest.begin() + static_cast<std::ptrdiff_t>(worst), rest.end());
  for (size_t j = 0; j < worst; ++j) plotted.push_back(rest[j].second);
  std::sort(plotted.begin(), plotted.end());
  return plotted;
}

std::string ReportHtml(const FitResultFile& result) {
  // the plotted sequences' PNGs; "" for the others (not plotted)
  std::vector<std::string> pngs(result.sequences.size()), held_out(result.validation.size());
  for (const size_t i : PlottedSequences(result.sequences))
    pngs[i] = SequencePng(result, result.sequences[i]);
  for (const size_t i : PlottedSequences(result.validation))
    held_out[i] = SequencePng(result, result.validation[i], true);
  return Page(result, pngs, held_out);
}

int WriteReport(const FitResultFile& result, const std::string& dir, const ReportOptions& options,
                std::string* summary) {
  const auto start = std::chrono::steady_clock::now();
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) throw ReportError(dir + ": no such directory");
  const std::filesystem::path d(dir);

  // the plots, then the page that embeds the sequence plots
  std::vector<std::string> written;
  WriteFile((d / "cost.png").string(), CostPng(result));
  written.push_back("cost.png");
  WriteFile((d / "parameters.png").string(), ParametersPng(result));
  written.push_back("parameters.png");
  // the plotted fitted sequences (seq_*.png), then the held-out ones (val_*.png); "" for a
  // sequence not plotted (PlottedSequences)
  std::vector<std::string> pngs(result.sequences.size()), held_out_pngs(result.validation.size());
  std::set<std::string> names;
  for (const bool held_out : {false, true}) {
    const char* prefix = held_out ? "val_" : "seq_";
    const std::vector<SequenceResult>& list = held_out ? result.validation : result.sequences;
    for (const size_t i : PlottedSequences(list)) {
      const SequenceResult& s = list[i];
      // two names that sanitize alike: _2, _3, ...
      std::string file = SequenceFileName(s.name, prefix);
      for (int k = 2; !names.insert(file).second; ++k) {
        file = SequenceFileName(s.name + "_" + std::to_string(k), prefix);
      }
      std::string& png = (held_out ? held_out_pngs : pngs)[i];
      png = SequencePng(result, s, held_out);
      WriteFile((d / file).string(), png);
      written.push_back(file);
    }
  }
  // the motion clip, also a file of its own
  // the experiment loaded again: the motion clip and the input plots (never an error)
  const LoggedExperiment logged = LoadLoggedExperiment(result);
  const MotionResult motion = MakeMotion(result, logged, options.motion);
  if (!motion.webp.empty()) {
    WriteFile((d / "motion.webp").string(), motion.webp);
    written.push_back("motion.webp");
  } else {
    std::filesystem::remove(d / "motion.webp", ec);  // a clip of an earlier report
  }
  WriteFile((d / "report.html").string(),
            Page(result, pngs, held_out_pngs, MotionHtml(motion), &logged));
  written.insert(written.begin(), "report.html");

  if (summary != nullptr) {
    // a few lines for the terminal
    size_t unidentifiable = 0;
    std::string unid_names;
    for (const ParameterEstimate& p : result.parameters) {
      if (p.identifiable) continue;
      unid_names += (unidentifiable++ ? ", " : "") + p.name;
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const std::string termination = TerminationText(result.termination);
    std::ostringstream s;
    s << "report " << result.name << " (" << dir << ")\n"
      << "  status      " << result.status << (termination.empty() ? "" : " (" + termination + ")")
      << "\n";
    if (std::isnan(result.initial_cost) || std::isnan(result.final_cost)) {
      s << "  cost        none: the solver stopped before its first iteration\n";
    } else {
      s << "  cost        " << Num(result.initial_cost, 4) << " -> " << Num(result.final_cost, 4)
        << " in " << result.iterations << " iterations\n";
    }
    s << "  parameters  " << result.parameters.size();
    if (unidentifiable > 0) s << ", " << unidentifiable << " unidentifiable: " << unid_names;
    s << "\n  motion      ";
    if (motion.webp.empty()) {
      s << "none: " << motion.note;
    } else {
      char line[160];
      std::snprintf(line, sizeof(line), "%s: %d frames %dx%d at %.1f fps, %.2f s, %.0f KiB",
                    motion.sequence.c_str(), motion.frames, motion.width, motion.height, motion.fps,
                    motion.seconds, motion.webp.size() / 1024.0);
      s << line;
    }
    s << "\n  wrote       " << (d / "report.html").string();
    for (size_t i = 1; i < written.size(); ++i) s << (i == 1 ? " + " : ", ") << written[i];
    char buf[32];
    std::snprintf(buf, sizeof(buf), " in %.2f s\n", seconds);
    s << buf;
    *summary = s.str();
  }
  return static_cast<int>(written.size());
}

int WriteReport(const FitResultFile& result, const std::string& dir, std::string* summary) {
  return WriteReport(result, dir, ReportOptions(), summary);
}

int WriteReport(const std::string& dir, const ReportOptions& options, std::string* summary) {
  return WriteReport(io::ReadResult(dir), dir, options, summary);
}

int WriteReport(const std::string& dir, std::string* summary) {
  return WriteReport(dir, ReportOptions(), summary);
}

}  // namespace mjsysid::report

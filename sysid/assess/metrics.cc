#include "sysid/assess/metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace mjsysid {
namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
}  // namespace

double Nrmse(const Eigen::Ref<const Eigen::VectorXd>& measured,
             const Eigen::Ref<const Eigen::VectorXd>& simulated) {
  if (measured.size() == 0 || measured.size() != simulated.size()) return kNaN;
  // over the measured cells (NaN: not measured, as the fit masks them): |y - yhat| / |y - mean(y)|,
  // the same as RMS error over the population std; a simulated NaN is a failed simulation
  double sum = 0;
  long long n = 0;
  for (Eigen::Index k = 0; k < measured.size(); ++k) {
    if (std::isnan(measured[k])) continue;
    sum += measured[k];
    ++n;
  }
  if (n == 0) return kNaN;
  const double mean = sum / static_cast<double>(n);
  double spread = 0, error = 0;
  for (Eigen::Index k = 0; k < measured.size(); ++k) {
    if (std::isnan(measured[k])) continue;
    spread += (measured[k] - mean) * (measured[k] - mean);
    error += (measured[k] - simulated[k]) * (measured[k] - simulated[k]);
  }
  if (!(spread > 0)) return kNaN;
  return std::sqrt(error / spread);
}

double FitPercent(double nrmse) { return 100.0 * (1.0 - nrmse); }

std::vector<std::string> ChannelNames(const SequenceResult& s) {
  std::vector<std::string> out;
  for (size_t i = 0; i < s.sensor_names.size() && i < s.sensor_dims.size(); ++i) {
    for (int c = 0; c < s.sensor_dims[i]; ++c) {
      out.push_back(s.sensor_dims[i] == 1 ? s.sensor_names[i]
                                          : s.sensor_names[i] + "[" + std::to_string(c) + "]");
    }
  }
  return out;
}

std::vector<ChannelFit> ChannelFits(const SequenceResult& s) {
  std::vector<ChannelFit> out;
  const std::vector<std::string> names = ChannelNames(s);
  for (Eigen::Index col = 0; col < static_cast<Eigen::Index>(names.size()); ++col) {
    if (col >= s.measured.cols()) return out;
    ChannelFit f;
    f.channel = names[static_cast<size_t>(col)];
    const Eigen::VectorXd y = s.measured.col(col);
    // a simulation that is missing (e.g. failed) gives NaN, not a number for another column
    f.nrmse_initial =
        s.simulated_initial.cols() > col ? Nrmse(y, s.simulated_initial.col(col)) : kNaN;
    const double final_fit =
        s.simulated_final.cols() > col ? Nrmse(y, s.simulated_final.col(col)) : kNaN;
    if (s.simulated_one_piece.rows() > 0) {
      // multiple shooting: the headline is the estimate in one piece, the segments' beside it
      f.nrmse_final =
          s.simulated_one_piece.cols() > col ? Nrmse(y, s.simulated_one_piece.col(col)) : kNaN;
      f.nrmse_segments = final_fit;
      f.fit_segments = FitPercent(f.nrmse_segments);
    } else {
      f.nrmse_final = final_fit;
    }
    f.fit_initial = FitPercent(f.nrmse_initial);
    f.fit_final = FitPercent(f.nrmse_final);
    out.push_back(std::move(f));
  }
  return out;
}

FitSummary SummarizeFits(const std::vector<ChannelFit>& fits, bool initial) {
  std::vector<double> v;
  for (const ChannelFit& f : fits) {
    const double x = initial ? f.fit_initial : f.fit_final;
    if (std::isfinite(x)) v.push_back(x);
  }
  if (v.empty()) return {kNaN, kNaN};
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  const double median = n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
  return {v.front(), median};
}

}  // namespace mjsysid

#include "tools/report/correlation.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "tools/report/axes.h"
#include "tools/report/page.h"

namespace mjsysid::report {
namespace {

// a cell's background: white at 0, towards red (+1) or blue (-1) with |r|
std::string CellColor(double r) {
  const double a = std::min(1.0, std::abs(r));
  const int fade = static_cast<int>(std::lround(255 * (1 - 0.75 * a)));
  char buf[32];
  if (r >= 0) {
    std::snprintf(buf, sizeof(buf), "rgb(255,%d,%d)", fade, fade);
  } else {
    std::snprintf(buf, sizeof(buf), "rgb(%d,%d,255)", fade, fade);
  }
  return buf;
}

// r with two decimals ("&minus;" for the sign)
std::string Corr(double r) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.2f", std::abs(r));
  return (r < 0 && std::lround(100 * r) != 0 ? "&minus;" : "") + std::string(buf);
}

}  // namespace

Eigen::MatrixXd CorrelationMatrix(const Eigen::MatrixXd& covariance) {
  const Eigen::Index n = covariance.rows();
  Eigen::MatrixXd r =
      Eigen::MatrixXd::Constant(n, covariance.cols(), std::numeric_limits<double>::quiet_NaN());
  if (covariance.cols() != n) return r;
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j < n; ++j) {
      const double vi = covariance(i, i), vj = covariance(j, j);
      if (!(vi > 0 && vj > 0 && std::isfinite(vi) && std::isfinite(vj))) continue;
      r(i, j) = i == j ? 1.0 : covariance(i, j) / std::sqrt(vi * vj);
    }
  }
  return r;
}

std::string CorrelationSection(const io::FitResultFile& result) {
  std::ostringstream h;
  h << "<h2>Parameter correlation</h2>\n";
  const auto n = static_cast<Eigen::Index>(result.parameters.size());
  const Eigen::MatrixXd& cov = result.uncertainty.covariance;
  if (n < 2 || cov.rows() != n || cov.cols() != n) {
    h << "<p class=\"muted\">"
      << (n < 2 ? "fewer than two parameters" : "no covariance of the parameters in the results")
      << "</p>\n";
    return h.str();
  }
  const Eigen::MatrixXd r = CorrelationMatrix(cov);
  h << "<p class=\"muted\">correlation of the estimates, from their covariance: near &plusmn;1 the "
       "data tell the pair's combination, not each parameter; a dash: no variance (fixed or "
       "unidentifiable). Columns are numbered as the rows.";
  if (!result.intervals_valid) h << " The fit did not converge: these describe no estimate.";
  h << "</p>\n<table class=\"correlation\">\n<tr><th></th>";
  for (Eigen::Index j = 0; j < n; ++j) h << "<th class=\"n\">" << j + 1 << "</th>";
  h << "</tr>\n";
  for (Eigen::Index i = 0; i < n; ++i) {
    const std::string& row = result.parameters[static_cast<size_t>(i)].name;
    h << "<tr><th>" << i + 1 << " " << HtmlEscape(row) << "</th>";
    for (Eigen::Index j = 0; j < n; ++j) {
      const std::string& col = result.parameters[static_cast<size_t>(j)].name;
      if (std::isnan(r(i, j))) {
        h << "<td class=\"n\" title=\"" << HtmlEscape(row) << " / " << HtmlEscape(col)
          << ": no variance\">&ndash;</td>";
        continue;
      }
      h << "<td class=\"n\" style=\"background:" << CellColor(r(i, j)) << "\" title=\""
        << HtmlEscape(row) << " / " << HtmlEscape(col) << ": " << Corr(r(i, j)) << "\">"
        << Corr(r(i, j)) << "</td>";
    }
    h << "</tr>\n";
  }
  h << "</table>\n";
  // the strong pairs in words
  std::vector<std::string> strong;
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = i + 1; j < n; ++j) {
      if (!(std::abs(r(i, j)) >= kStrongCorrelation)) continue;
      strong.push_back(HtmlEscape(result.parameters[static_cast<size_t>(i)].name) + " and " +
                       HtmlEscape(result.parameters[static_cast<size_t>(j)].name) +
                       " (r = " + Corr(r(i, j)) + ")");
    }
  }
  if (strong.empty()) {
    h << "<p class=\"muted\">no pair correlated beyond &plusmn;" << Num(kStrongCorrelation, 2)
      << "</p>\n";
  } else {
    h << "<p>strongly correlated (|r| &ge; " << Num(kStrongCorrelation, 2)
      << "): the data tell their combination far better than each:</p>\n<ul class=\"strong\">\n";
    for (const std::string& s : strong) h << "<li>" << s << "</li>\n";
    h << "</ul>\n";
  }
  return h.str();
}

}  // namespace mjsysid::report

// The QR fold of sysid/row_triangle.h.
#include "sysid/solve/row_triangle.h"

#include <Eigen/QR>
#include <algorithm>
#include <stdexcept>
#include <string>

namespace mjsysid {

RowTriangle::RowTriangle(int n) { Reset(n); }

void RowTriangle::Reset(int n) {
  n_ = n;
  rows_ = 0;
  r_.resize(0, n);
}

// stacked_ = [R; count rows the caller fills in]
void RowTriangle::Stack(Eigen::Index count) {
  const Eigen::Index top = r_.rows();
  stacked_.resize(top + count, n_);
  stacked_.topRows(top) = r_;
}

// [R; chunk] -> the R of its thin QR (same normal matrix as every row added so far)
void RowTriangle::Fold(Eigen::Index count) {
  const Eigen::HouseholderQR<Eigen::Ref<Eigen::MatrixXd>> qr(stacked_);
  const Eigen::Index kept = std::min<Eigen::Index>(stacked_.rows(), n_);
  r_ = qr.matrixQR().topRows(kept).triangularView<Eigen::Upper>();
  rows_ += count;
}

void RowTriangle::Add(const Eigen::Ref<const RowMatrix>& rows) {
  if (rows.cols() != n_) {
    throw std::invalid_argument("RowTriangle: rows have " + std::to_string(rows.cols()) +
                                " columns, expected " + std::to_string(n_));
  }
  for (Eigen::Index first = 0; first < rows.rows(); first += kChunkRows) {
    const Eigen::Index count = std::min<Eigen::Index>(kChunkRows, rows.rows() - first);
    Stack(count);
    stacked_.bottomRows(count) = rows.middleRows(first, count);
    Fold(count);
  }
}

void RowTriangle::Add(const Eigen::Ref<const RowMatrix>& J,
                      const Eigen::Ref<const Eigen::VectorXd>& r) {
  if (J.cols() != n_ - 1 || r.size() != J.rows()) {
    throw std::invalid_argument("RowTriangle: [J r] is " + std::to_string(J.rows()) + " x " +
                                std::to_string(J.cols()) + " and " + std::to_string(r.size()) +
                                " residuals, expected " + std::to_string(n_ - 1) + " columns");
  }
  for (Eigen::Index first = 0; first < J.rows(); first += kChunkRows) {
    const Eigen::Index count = std::min<Eigen::Index>(kChunkRows, J.rows() - first);
    Stack(count);
    stacked_.bottomLeftCorner(count, n_ - 1) = J.middleRows(first, count);
    stacked_.bottomRightCorner(count, 1) = r.segment(first, count);
    Fold(count);
  }
}

Eigen::MatrixXd RowTriangle::Square() const {
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(n_, n_);
  out.topRows(r_.rows()) = r_;
  return out;
}

}  // namespace mjsysid

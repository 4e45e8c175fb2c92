// StateBlocks: the free initial states of a fit's segments, Ceres parameter blocks stored
// contiguously (sysid/solve/fit_state.h FitVariables::states).
#pragma once

#include <cstddef>
#include <vector>

namespace mjsysid {

// The state blocks of a fit (the segments' initial states, Ceres parameter blocks), stored
// contiguously in block order. Ceres keeps the blocks of an elimination group in a
// std::set<double*>, i.e. ordered by address, and orders the Schur elimination and the residual
// blocks by it: with one allocation per block that order followed the heap (other threads'
// allocations, the thread count), and so did the rounding of every sum over segments (measured:
// the pendulum in 100-step segments, iteration 0's cost 1 ulp apart between 1 and 2 threads,
// the finger 29 vs 49 iterations). Contiguous storage makes it the block order, always.
// Pointers (data()) stay valid until the next push_back or clear.
class StateBlocks {
 public:
  template <class T>
  struct View {
    T* p;
    int n;
    T* data() const { return p; }
    size_t size() const { return static_cast<size_t>(n); }
    T* begin() const { return p; }
    T* end() const { return p + n; }
  };
  void clear() {
    values_.clear();
    first_.clear();
  }
  size_t size() const { return first_.size(); }
  bool empty() const { return first_.empty(); }
  // appends a block with the values x
  void push_back(const std::vector<double>& x) {
    first_.push_back(values_.size());
    values_.insert(values_.end(), x.begin(), x.end());
  }
  View<double> operator[](size_t i) { return {values_.data() + first_[i], Size(i)}; }
  View<const double> operator[](size_t i) const { return {values_.data() + first_[i], Size(i)}; }

 private:
  int Size(size_t i) const {
    const size_t end = i + 1 < first_.size() ? first_[i + 1] : values_.size();
    return static_cast<int>(end - first_[i]);
  }
  std::vector<double> values_;  // every block, in order
  std::vector<size_t> first_;   // per block: its first value
};

}  // namespace mjsysid

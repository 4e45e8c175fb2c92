// Pickling of the results (FitResult, ResultFile, ExperimentFit) for the Python module: every
// field of sysid/types.h's result structs written to bytes and read back exactly (doubles by
// their bits, NaN and inf kept), so that a result survives pickle.dumps / loads, copy.deepcopy
// and multiprocessing. The bytes are this module's, not a file format: they start with a tag and
// a version, and bytes of another version are refused (ValueError) rather than misread.
//
// One function per struct lists its fields once (Fields below); the same list writes and reads.
// A field added to or removed from one of these structs must be added to or removed from its
// list, and kVersion raised (tests/python/test_fit_api.py compares a round trip attribute by
// attribute, every public one).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <cstring>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "sysid/io/result.h"
#include "sysid/types.h"

namespace mjsysid::python {

// writes (reading = false) or reads (reading = true) the bytes of the fields given to it
class Archive {
 public:
  static constexpr const char* kTag = "mjsysid-result-pickle";
  static constexpr int kVersion = 1;

  // a writer
  Archive() = default;
  // a reader of `bytes` (a copy of their pointer: they must outlive the reader)
  explicit Archive(const std::string& bytes) : reading_(true), in_(&bytes) {}

  bool reading() const { return reading_; }
  const std::string& bytes() const { return out_; }

  // the tag (its bytes, no count: any input is checked against it) and the version: written,
  // or read and checked
  void Header() {
    const size_t n = std::strlen(kTag);
    if (!reading_) {
      out_.append(kTag, n);
    } else if (in_->compare(0, n, kTag) != 0) {
      throw std::invalid_argument(std::string("not a pickled mjsysid result (no '") + kTag +
                                  "' tag)");
    } else {
      at_ = n;
    }
    int version = kVersion;
    Field(version);
    if (version != kVersion) {
      throw std::invalid_argument("a pickled mjsysid result of version " + std::to_string(version) +
                                  "; this module reads version " + std::to_string(kVersion));
    }
  }
  // the whole input read (after the last field)
  void End() const {
    if (reading_ && at_ != in_->size()) {
      throw std::invalid_argument("a pickled mjsysid result with " +
                                  std::to_string(in_->size() - at_) + " bytes left over");
    }
  }

  template <typename... T>
  void operator()(T&... fields) {
    (Field(fields), ...);
  }

 private:
  void Bytes(void* p, size_t n) {
    if (!reading_) {
      out_.append(static_cast<const char*>(p), n);
      return;
    }
    if (at_ + n > in_->size()) throw std::invalid_argument("a truncated pickled mjsysid result");
    std::memcpy(p, in_->data() + at_, n);
    at_ += n;
  }
  // a count, checked against the bytes left when read (a corrupt count allocates nothing)
  size_t Count(size_t n, size_t bytes_each) {
    uint64_t c = n;
    Bytes(&c, sizeof(c));
    if (reading_ && bytes_each > 0 && c > (in_->size() - at_) / bytes_each) {
      throw std::invalid_argument("a corrupt pickled mjsysid result (count " + std::to_string(c) +
                                  ")");
    }
    return static_cast<size_t>(c);
  }

  template <typename T>
  void Field(T& x) {
    if constexpr (std::is_arithmetic_v<T>) {
      Bytes(&x, sizeof(T));
    } else if constexpr (std::is_enum_v<T>) {
      int64_t v = static_cast<int64_t>(x);
      Bytes(&v, sizeof(v));
      x = static_cast<T>(v);
    } else {
      Fields(*this, x);  // a struct: its list below
    }
  }
  void Field(std::string& s) {
    s.resize(Count(s.size(), 1));
    if (!s.empty()) Bytes(&s[0], s.size());
  }
  template <typename T>
  void Field(std::optional<T>& x) {
    bool has = x.has_value();
    Field(has);
    if (reading_) x = has ? std::optional<T>(T()) : std::nullopt;
    if (has) Field(*x);
  }
  template <typename T>
  void Field(std::vector<T>& v) {
    v.resize(Count(v.size(), 1));
    for (auto& x : v) Field(x);
  }
  void Field(std::vector<bool>& v) {
    v.resize(Count(v.size(), 1));
    for (size_t i = 0; i < v.size(); ++i) {
      bool b = v[i];
      Field(b);
      v[i] = b;
    }
  }
  template <typename K, typename V>
  void Field(std::map<K, V>& m) {
    const size_t n = Count(m.size(), 1);
    if (!reading_) {
      for (auto& [k, v] : m) {
        K key = k;
        Field(key);
        Field(v);
      }
      return;
    }
    m.clear();
    for (size_t i = 0; i < n; ++i) {
      K key{};
      V value{};
      Field(key);
      Field(value);
      m.emplace(std::move(key), std::move(value));
    }
  }
  template <typename S, int R, int C, int O, int MR, int MC>
  void Field(Eigen::Matrix<S, R, C, O, MR, MC>& x) {
    int64_t rows = x.rows(), cols = x.cols();
    Field(rows);
    Field(cols);
    if (reading_) {
      if (rows < 0 || cols < 0 ||
          (rows > 0 && static_cast<uint64_t>(cols) >
                           (in_->size() - at_) / sizeof(S) / static_cast<uint64_t>(rows))) {
        throw std::invalid_argument("a corrupt pickled mjsysid result (a matrix " +
                                    std::to_string(rows) + " x " + std::to_string(cols) + ")");
      }
      x.resize(rows, cols);
    }
    if (x.size() > 0) Bytes(x.data(), sizeof(S) * x.size());
  }

  bool reading_ = false;
  std::string out_;
  const std::string* in_ = nullptr;
  size_t at_ = 0;
};

// --- the fields of each struct, in one list each (written and read alike) ---

inline void Fields(Archive& a, ParameterEstimate& p) {
  a(p.name, p.value, p.initial, p.std_error, p.ci95_low, p.ci95_high, p.at_lower, p.at_upper,
    p.identifiable, p.truth, p.timestep_bias);
}
inline void Fields(Archive& a, Uncertainty& u) {
  a(u.covariance, u.std_error, u.identifiable, u.singular_values, u.rank, u.residual_variance,
    u.dof, u.unidentifiable);
}
inline void Fields(Archive& a, ResidualDiagnostics& d) {
  a(d.channel, d.samples, d.mean, d.rms, d.sigma, d.sigma_from_log, d.ratio, d.bias_units, d.lag1,
    d.tau, d.portmanteau_p, d.white);
}
inline void Fields(Archive& a, IterationInfo& i) {
  a(i.iteration, i.cost, i.step_norm, i.gradient_norm, i.seconds, i.successful, i.parameters);
}
inline void Fields(Archive& a, ChannelFit& f) {
  a(f.channel, f.nrmse_initial, f.nrmse_final, f.fit_initial, f.fit_final, f.nrmse_segments,
    f.fit_segments);
}
inline void Fields(Archive& a, SequenceResult& s) {
  a(s.name, s.model, s.sensor_names, s.sensor_dims, s.time, s.measured, s.simulated_initial,
    s.simulated_final, s.simulated_one_piece, s.x0_final, s.channel_fits, s.missing, s.state_names,
    s.state_dims, s.state_measured, s.state_simulated_initial, s.state_simulated_final,
    s.state_simulated_one_piece, s.state_residual_dims, s.state_residual_final);
}
inline void Fields(Archive& a, StartResult& s) {
  a(s.start, s.estimate, s.initial_cost, s.final_cost, s.status, s.iterations, s.error);
}
inline void Fields(Archive& a, ParameterSpread& s) { a(s.name, s.min, s.max, s.relative); }
inline void Fields(Archive& a, SegmentRecord& s) {
  a(s.choice, s.start_source, s.weights, s.held_iterations, s.held_initial_cost, s.held_final_cost);
}
inline void Fields(Archive& a, DerivedQuantity& d) {
  a(d.name, d.unit, d.value, d.std_error, d.ci95_low, d.ci95_high, d.derived_from, d.truth);
}
inline void Fields(Archive& a, IntervalCheckRecord& r) {
  a(r.kind, r.evaluations, r.skipped, r.parameters, r.rugged, r.dynamics_jump, r.cost_not_smooth,
    r.envelope, r.wide_fraction, r.read_text);
}
inline void Fields(Archive& a, FitTermination& t) {
  a(t.kind, t.solver_message, t.iteration, t.fraction, t.largest, t.jacobian_iteration,
    t.step_std_errors, t.read_text);
}
inline void Fields(Archive& a, FitResult::EventWindows& e) {
  a(e.window, e.events, e.masked, e.sensors);
}
inline void Fields(Archive& a, LedgerRow& r) {
  a(r.phase, r.entries, r.steps, r.seconds, r.critical_steps, r.batch_seconds, r.batches,
    r.wake_seconds, r.wait_seconds, r.batch_cpu_seconds);
}
inline void Fields(Archive& a, FitResult::Diagnostics::Reduction& r) {
  a(r.recorded, r.used, r.collision_pairs, r.collision_pairs_off, r.geoms_off, r.disabled,
    r.guard_trips);
}
inline void Fields(Archive& a, FitResult::Diagnostics& d) {
  a(d.simulation_steps, d.jacobian_mode, d.reduction, d.ledger, d.covariance_jacobian_iteration,
    d.last_step_std_errors, d.reused_folds, d.folds, d.ahead_folds);
}
inline void Fields(Archive& a, FitResult& r) {
  a(r.parameters, r.initial_cost, r.final_cost, r.iterations, r.converged, r.interrupted, r.outcome,
    r.intervals_valid, r.chi2_ratio, r.sensor_chi2_ratio, r.sensor_noise_ratio, r.sigma_from_log,
    r.termination, r.num_residuals, r.uncertainty, r.residuals, r.interval_inflation,
    r.intervals_from, r.timestep_check, r.subset_start, r.jacobian, r.trace, r.sequences,
    r.warnings, r.seconds, r.validation, r.starts, r.best_start, r.start_spread,
    r.segment_steps_used, r.segment_reason, r.derived, r.interval_check, r.event_windows,
    r.gauss_newton_converged, r.diagnostics);
}
inline void Fields(Archive& a, io::InputHash& h) { a(h.role, h.path, h.sha256); }
inline void Fields(Archive& a, io::FitResultFile& f) {
  a(static_cast<FitResult&>(f), f.name, f.experiment, f.created, f.status, f.run_id,
    f.mjsysid_version, f.mujoco_version, f.solver, f.identified_models, f.input_hashes);
}

// the bytes of `result` (a FitResult or a struct with a Fields list)
template <typename T>
std::string Pickled(const T& result) {
  Archive a;
  a.Header();
  a(const_cast<T&>(result));  // written only: the writer reads every field, changes none
  return a.bytes();
}

// `result` read from `bytes` (written by Pickled of the same type)
template <typename T>
void Unpickle(const std::string& bytes, T* result) {
  Archive a(bytes);
  a.Header();
  a(*result);
  a.End();
}

}  // namespace mjsysid::python

// Internal to sysid/io/result*.cc: the one table of result.yaml's fields (and of the ones result.h5
// keeps as root attributes). VisitResultFields lists every field once, in file order, with its key,
// its type and when it is written; the YAML writer, the YAML reader and result.h5's root attributes
// are visitors of it, so a new field is one line here. One visitor lives outside sysid/io: the
// Python results' to_dict() (python/src/result_dict.cc), result.yaml's keys in Python objects.
//
// A visitor V has, for a key K (FieldKey) and a value of the result (const for writers):
//   Text(K, std::string), Int(K, int), Number(K, double), Number(K, std::optional<double>: written
//   when set), Bool(K, bool), Pair(K, low, high: [low, high]), Numbers(K, Eigen::VectorXd),
//   Status(K, FitStatus: its name), Flags(K, at_lower, at_upper, identifiable: the flag names),
//   Texts(K, Style, list of text), Warnings(K, list of text: result.yaml groups those that recur
//   per sequence, sysid/io/warnings.h), TextMap(K, Style, map of text), Map(K, Style, written, f: a
//   nested map whose fields f(visitor) lists), List(K, Style of the entries, vector, f: one map per
//   entry, f(visitor, entry) lists its fields), FitMetrics(K, result: written only, recomputed from
//   result.h5 when read), Record(K, kind key, record: a record of the result written as its text
//   under K, then its kind's name under the kind key when known, a kind key {nullptr} for a record
//   without kinds; see RecordText below).
#pragma once

#include <Eigen/Core>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "sysid/io/result.h"

namespace mjsysid::io::result_internal {

// the names of a parameter's `flags` (Flags below)
inline constexpr const char* kFlags[] = {"at_lower_bound", "at_upper_bound", "unidentifiable"};

// when a field is written, and whether a reader needs it
enum class Presence {
  kRequired,  // always written; a reader fails without it
  kOptional,  // always written; a reader keeps the default without it (files of older versions)
  kWhenSet,   // written only when set (non-empty text or list, a value, Map's `written`); optional
};

// how a list or map is laid out in result.yaml
enum class Style {
  kBlock,             // one entry per line
  kFlow,              // [a, b] or {a: 1}
  kBlockOrEmptyFlow,  // one entry per line; [] or {} when empty
};

struct FieldKey {
  const char* name;
  Presence presence = Presence::kRequired;
  bool h5 = false;  // also a root attribute of result.h5
};

// The records of FitResult (sysid/types.h) as result.yaml keeps them: the text (rendered by the
// one function next to the type) and the kind's name ("": not written, kWhenSet). A record read
// back keeps the text as read (read_text; the numbers are not in the file) and the kind; a file
// without the kind key (written before the kinds) gives the kind kUnknown, an empty text the
// record's default (nothing recorded). SetRecord is false for a kind name it does not know.
inline std::string RecordText(const FitTermination& t) { return TerminationText(t); }
inline std::string RecordKind(const FitTermination& t) {
  const bool known =
      t.kind != FitTermination::Kind::kNone && t.kind != FitTermination::Kind::kUnknown;
  return known ? TerminationKindName(t.kind) : "";
}
inline bool SetRecord(const std::string& text, const std::optional<std::string>& kind,
                      FitTermination* t) {
  *t = FitTermination();
  if (kind) {
    const std::optional<FitTermination::Kind> k = TerminationKindFromName(*kind);
    if (!k) return false;
    t->kind = *k;
  } else if (!text.empty()) {
    t->kind = FitTermination::Kind::kUnknown;
  }
  t->read_text = text;
  return true;
}
inline std::string RecordText(const IntervalCheckRecord& r) { return IntervalCheckText(r); }
inline std::string RecordKind(const IntervalCheckRecord& r) {
  const bool known =
      r.kind != IntervalCheckRecord::Kind::kNotRun && r.kind != IntervalCheckRecord::Kind::kUnknown;
  return known ? IntervalCheckKindName(r.kind) : "";
}
inline bool SetRecord(const std::string& text, const std::optional<std::string>& kind,
                      IntervalCheckRecord* r) {
  *r = IntervalCheckRecord();
  if (kind) {
    const std::optional<IntervalCheckRecord::Kind> k = IntervalCheckKindFromName(*kind);
    if (!k) return false;
    r->kind = *k;
  } else if (!text.empty()) {
    r->kind = IntervalCheckRecord::Kind::kUnknown;
  }
  r->read_text = text;
  return true;
}
// the segments have no kind: the text read back is the record's choice
inline std::string RecordText(const SegmentRecord& r) { return SegmentReasonText(r); }
inline std::string RecordKind(const SegmentRecord&) { return ""; }
inline bool SetRecord(const std::string& text, const std::optional<std::string>& kind,
                      SegmentRecord* r) {
  *r = SegmentRecord();
  r->choice = text;
  return !kind;
}

// a reader's note that an optional block was present (a writer's result is const)
inline void MarkPresent(bool& flag) { flag = true; }
inline void MarkPresent(const bool&) {}

// one entry of `parameters`
template <class V, class P>
void VisitParameterFields(V& v, P& p) {
  v.Text({"name"}, p.name);
  v.Number({"value"}, p.value);
  v.Number({"initial"}, p.initial);
  v.Number({"std"}, p.std_error);
  v.Pair({"ci95"}, p.ci95_low, p.ci95_high);
  v.Flags({"flags"}, p.at_lower, p.at_upper, p.identifiable);
  v.Number({"truth", Presence::kWhenSet}, p.truth);
  v.Number({"timestep_bias", Presence::kWhenSet}, p.timestep_bias);
}

// one entry of `derived` (sysid/assess/derived_inertials.h)
template <class V, class D>
void VisitDerivedFields(V& v, D& d) {
  v.Text({"name"}, d.name);
  v.Text({"unit"}, d.unit);
  v.Number({"value"}, d.value);
  v.Number({"std"}, d.std_error);
  v.Pair({"ci95"}, d.ci95_low, d.ci95_high);
  v.Text({"derived_from"}, d.derived_from);
  v.Number({"truth", Presence::kWhenSet}, d.truth);
}

// one entry of `residuals` (sysid/assess/residual_diagnostics.h)
template <class V, class D>
void VisitResidualFields(V& v, D& d) {
  v.Text({"channel"}, d.channel);
  v.Int({"samples"}, d.samples);
  v.Number({"mean"}, d.mean);
  v.Number({"rms"}, d.rms);
  v.Number({"sigma"}, d.sigma);
  // the sigma estimated from the log (sigma: auto); absent: stated (files before sigma: auto)
  v.Bool({"sigma_from_log", Presence::kOptional}, d.sigma_from_log);
  v.Number({"rms_over_sigma"}, d.ratio);
  v.Number({"bias_std_errors"}, d.bias_units);
  v.Number({"lag1"}, d.lag1);
  v.Number({"correlation_samples"}, d.tau);
  v.Number({"portmanteau_p"}, d.portmanteau_p);
  v.Bool({"white"}, d.white);
}

// one entry of `fit_metrics` (sysid/assess/metrics.h): a sequence, its role (fit | validation)
// and per channel the % fit and NRMSE at the start and at the estimate; a fit in segments
// (simulated_one_piece set) also segment by segment, fit_final then the estimate in one piece.
// Written only: ReadResult recomputes them from result.h5.
template <class V, class S>
void VisitFitMetricsFields(V& v, const S& s, const std::string& role) {
  v.Text({"sequence"}, s.name);
  v.Text({"role"}, role);
  const bool segments = s.simulated_one_piece.rows() > 0;
  v.List({"channels"}, Style::kFlow, s.channel_fits, [segments](auto& e, const auto& f) {
    e.Text({"channel"}, f.channel);
    e.Number({"fit_initial"}, f.fit_initial);
    e.Number({"fit_final"}, f.fit_final);
    e.Number({"nrmse_initial"}, f.nrmse_initial);
    e.Number({"nrmse_final"}, f.nrmse_final);
    if (segments) {
      e.Number({"fit_segments"}, f.fit_segments);
      e.Number({"nrmse_segments"}, f.nrmse_segments);
    }
  });
}

// one entry of `starts.runs` (values in the order of `parameters`)
template <class V, class S>
void VisitStartFields(V& v, S& s) {
  v.Numbers({"start"}, s.start);
  v.Numbers({"estimate"}, s.estimate);
  v.Number({"initial_cost"}, s.initial_cost);
  v.Number({"final_cost"}, s.final_cost);
  v.Status({"status"}, s.status);
  v.Int({"iterations"}, s.iterations);
  v.Text({"error", Presence::kWhenSet}, s.error);
}

// one entry of `starts.spread`
template <class V, class S>
void VisitSpreadFields(V& v, S& s) {
  v.Text({"name"}, s.name);
  v.Number({"min"}, s.min);
  v.Number({"max"}, s.max);
  v.Number({"relative"}, s.relative);
}

// one entry of `input_hashes` (sysid/run/input_hashes.h)
template <class V, class H>
void VisitInputHashFields(V& v, H& h) {
  v.Text({"role"}, h.role);
  v.Text({"path"}, h.path);
  v.Text({"sha256"}, h.sha256);
}

// every field of result.yaml after format and format_version, in file order
template <class V, class R>
void VisitResultFields(V& v, R& r) {
  // summary
  v.Text({"name"}, r.name);
  v.Text({"experiment"}, r.experiment);
  v.Text({"status", Presence::kRequired, true}, r.status);
  v.Record({"termination"}, {"termination_kind", Presence::kWhenSet}, r.termination);
  v.Text({"created"}, r.created);
  v.Text({"mjsysid_version"}, r.mjsysid_version);
  v.Text({"mujoco_version"}, r.mujoco_version);
  v.Text({"jacobian_mode"}, r.diagnostics.jacobian_mode);
  v.Text({"run_id", Presence::kWhenSet, true}, r.run_id);
  // whether std and ci95 mean something (only for status converged); absent: valid when converged
  v.Bool({"intervals_valid", Presence::kOptional, true}, r.intervals_valid);
  // what the intervals come from (white residuals, or widened by their correlation time: the
  // factor applied to the covariance); absent: white (files before the residual diagnostics)
  v.Text({"intervals_from", Presence::kWhenSet}, r.intervals_from);
  v.Number({"interval_inflation", Presence::kOptional}, r.interval_inflation);
  // the timestep check (sysid/fit/timestep_check.h): what it ran and found; absent: not run
  v.Text({"timestep_check", Presence::kWhenSet}, r.timestep_check);
  // the subset start (sysid/fit/subset_start.h): what it ran and whether it gave the start;
  // absent: not run
  v.Text({"subset_start", Presence::kWhenSet}, r.subset_start);
  v.Int({"iterations"}, r.iterations);
  v.Number({"initial_cost"}, r.initial_cost);
  v.Number({"final_cost"}, r.final_cost);
  v.Number({"residual_variance"}, r.uncertainty.residual_variance);
  v.Int({"num_residuals"}, r.num_residuals);
  v.Number({"wall_time_s"}, r.seconds);
  // multiple shooting as used (0: single shooting) and why
  v.Int({"segment_steps_used", Presence::kOptional}, r.segment_steps_used);
  v.Record({"segment_reason", Presence::kOptional}, {nullptr}, r.segment_reason);
  // whether the interval check ran and why (sysid/assess/interval_check.h); absent: no uncertainty
  // step
  v.Record({"interval_check", Presence::kWhenSet}, {"interval_check_kind", Presence::kWhenSet},
           r.interval_check);
  // the statistical stop before the last Jacobian (sysid/solve/gn_convergence.h): the covariance's
  // Jacobian is the previous iterate's; absent: the estimate's own
  v.Map({"covariance_jacobian", Presence::kWhenSet}, Style::kBlock,
        r.diagnostics.covariance_jacobian_iteration >= 0, [&](auto& m) {
          m.Int({"iteration"}, r.diagnostics.covariance_jacobian_iteration);
          m.Number({"last_step_std_errors"}, r.diagnostics.last_step_std_errors);
        });
  // auto's contact segments: the cells next to contact events left out (sysid/data/event_windows.h)
  v.Map({"event_windows", Presence::kWhenSet}, Style::kBlock, r.event_windows.masked > 0,
        [&](auto& m) {
          m.Int({"window"}, r.event_windows.window);
          m.Int({"events"}, r.event_windows.events);
          m.Int({"masked_cells"}, r.event_windows.masked);
          m.Texts({"sensors"}, Style::kFlow, r.event_windows.sensors);
        });
  // solver settings, as text
  v.TextMap({"solver"}, Style::kBlock, r.solver);
  v.List({"parameters"}, Style::kBlock, r.parameters,
         [](auto& e, auto& p) { VisitParameterFields(e, p); });
  // quantities derived from the estimate (body_inertial: mass, com, principal moments)
  v.List({"derived", Presence::kWhenSet}, Style::kBlock, r.derived,
         [](auto& e, auto& d) { VisitDerivedFields(e, d); });
  v.Texts({"unidentifiable"}, Style::kBlockOrEmptyFlow, r.uncertainty.unidentifiable);
  v.Warnings({"warnings"}, r.warnings);  // grouped per sequence (sysid/io/warnings.h)
  v.TextMap({"identified_models"}, Style::kBlockOrEmptyFlow, r.identified_models);
  // the files the fit read, by content (--resume and report refuse inputs changed since)
  v.List({"input_hashes", Presence::kWhenSet}, Style::kFlow, r.input_hashes,
         [](auto& e, auto& h) { VisitInputHashFields(e, h); });
  // per channel fit metrics (sysid/assess/metrics.h) of the fitted and the held-out sequences
  v.FitMetrics({"fit_metrics"}, r);
  // the residuals at the estimate per fitted channel, pooled over the fitted sequences: bias,
  // ratio to sigma, whiteness, correlation time (sysid/assess/residual_diagnostics.h)
  v.List({"residuals", Presence::kWhenSet}, Style::kBlock, r.residuals,
         [](auto& e, auto& d) { VisitResidualFields(e, d); });
  // multi-start: every start, the best, the spread
  v.Map({"starts", Presence::kWhenSet}, Style::kBlock, !r.starts.empty(), [&](auto& m) {
    m.Int({"best"}, r.best_start);
    m.List({"runs"}, Style::kBlock, r.starts, [](auto& e, auto& s) { VisitStartFields(e, s); });
    m.List({"spread"}, Style::kFlow, r.start_spread,
           [](auto& e, auto& s) { VisitSpreadFields(e, s); });
  });
  // the reduced model (FitOptions::reduce_model, core/reduced_model.h)
  auto& reduction = r.diagnostics.reduction;
  v.Map({"reduced", Presence::kWhenSet}, Style::kFlow, reduction.recorded, [&](auto& m) {
    MarkPresent(reduction.recorded);
    m.Bool({"used"}, reduction.used);
    m.Int({"collision_pairs"}, reduction.collision_pairs);
    m.Int({"collision_pairs_off"}, reduction.collision_pairs_off);
    m.Int({"geoms_off"}, reduction.geoms_off);
    m.Texts({"disabled"}, Style::kFlow, reduction.disabled);
    m.Int({"guard_trips"}, reduction.guard_trips);
  });
}

}  // namespace mjsysid::io::result_internal

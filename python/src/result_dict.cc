// to_dict() and to_pandas() of the result classes: a fit as result.yaml has it, in plain Python
// objects. The keys are result.yaml's: the dict is a visitor of the one table of its fields
// (sysid/io/result_fields.h, VisitResultFields), as the YAML writer is, so a new field of the file
// is a new key here without a line of this file. The tables of to_pandas() are made by
// mjsysid._frames from these dicts (pandas imported there, lazily).
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/string.h>

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "bindings.h"
#include "sysid/assess/metrics.h"
#include "sysid/io/result.h"
#include "sysid/io/result_fields.h"

namespace mjsysid::python {
namespace {

namespace ri = io::result_internal;

// A visitor of result_fields.h (see there) that puts each field into a dict under its key:
// numbers as float, integers as int, flags as the list of their names, lists and maps as Python
// lists and dicts. Unlike the YAML writer it keeps the warnings one string each (result.yaml groups
// those that recur per sequence) and writes NaN and infinities as floats.
class DictWriter {
 public:
  explicit DictWriter(nb::dict d) : d_(std::move(d)) {}

  void Text(const ri::FieldKey& k, const std::string& s) {
    if (k.presence == ri::Presence::kWhenSet && s.empty()) return;
    d_[k.name] = s;
  }
  template <class R>
  void Record(const ri::FieldKey& k, const ri::FieldKey& kind, const R& record) {
    Text(k, ri::RecordText(record));
    if (kind.name) Text(kind, ri::RecordKind(record));
  }
  void Int(const ri::FieldKey& k, int i) { d_[k.name] = i; }
  void Bool(const ri::FieldKey& k, bool b) { d_[k.name] = b; }
  void Number(const ri::FieldKey& k, double x) { d_[k.name] = x; }
  void Number(const ri::FieldKey& k, const std::optional<double>& x) {
    if (x) Number(k, *x);
  }
  void Pair(const ri::FieldKey& k, double low, double high) {
    nb::list l;
    l.append(low);
    l.append(high);
    d_[k.name] = l;
  }
  void Numbers(const ri::FieldKey& k, const Eigen::VectorXd& v) {
    nb::list l;
    for (Eigen::Index i = 0; i < v.size(); ++i) l.append(v[i]);
    d_[k.name] = l;
  }
  void Status(const ri::FieldKey& k, FitStatus s) { d_[k.name] = FitStatusName(s); }
  void Flags(const ri::FieldKey& k, bool at_lower, bool at_upper, bool identifiable) {
    nb::list l;
    if (at_lower) l.append(ri::kFlags[0]);
    if (at_upper) l.append(ri::kFlags[1]);
    if (!identifiable) l.append(ri::kFlags[2]);
    d_[k.name] = l;
  }
  void Texts(const ri::FieldKey& k, ri::Style, const std::vector<std::string>& items) {
    nb::list l;
    for (const std::string& item : items) l.append(item);
    d_[k.name] = l;
  }
  void Warnings(const ri::FieldKey& k, const std::vector<std::string>& items) {
    Texts(k, ri::Style::kBlock, items);
  }
  void TextMap(const ri::FieldKey& k, ri::Style, const std::map<std::string, std::string>& map) {
    nb::dict m;
    for (const auto& [key, value] : map) m[nb::str(key.c_str())] = value;
    d_[k.name] = m;
  }
  template <class F>
  void Map(const ri::FieldKey& k, ri::Style, bool written, F&& fields) {
    if (!written) return;
    DictWriter m{nb::dict()};
    fields(m);
    d_[k.name] = m.d_;
  }
  template <class T, class F>
  void List(const ri::FieldKey& k, ri::Style, const std::vector<T>& entries, F&& fields) {
    if (k.presence == ri::Presence::kWhenSet && entries.empty()) return;
    nb::list l;
    for (const T& entry : entries) {
      DictWriter e{nb::dict()};
      fields(e, entry);
      l.append(e.d_);
    }
    d_[k.name] = l;
  }
  void FitMetrics(const ri::FieldKey& k, const io::FitResultFile& r) {
    nb::list l;
    for (const std::vector<SequenceResult>* list : {&r.sequences, &r.validation}) {
      for (const SequenceResult& s : *list) {
        DictWriter e{nb::dict()};
        ri::VisitFitMetricsFields(e, s, list == &r.sequences ? "fit" : "validation");
        l.append(e.d_);
      }
    }
    d_[k.name] = l;
  }

  const nb::dict& dict() const { return d_; }

 private:
  nb::dict d_;
};

// the run's keys for a fit made in this process (mjsysid.fit): no file, no experiment
io::FitResultFile AsFile(const FitResult& r) {
  io::FitResultFile f;
  static_cast<FitResult&>(f) = r;
  f.status = FitStatusName(r.outcome);
  return f;
}

nb::dict DictOf(const io::FitResultFile& r) {
  DictWriter w{nb::dict()};
  ri::VisitResultFields(w, r);
  return w.dict();
}

nb::object Frames() { return nb::module_::import_("mjsysid._frames"); }

// the parameters' table of a to_dict() dict, with a bool column per flag name
nb::object ParametersFrame(const nb::dict& result) {
  nb::list flags;
  for (const char* flag : ri::kFlags) flags.append(flag);
  return Frames().attr("parameters_frame")(result, flags);
}

}  // namespace

void BindResultTables(nb::class_<FitResult>& fit_result,
                      nb::class_<io::FitResultFile, FitResult>& result_file,
                      nb::class_<ExperimentFit, io::FitResultFile>& experiment_fit,
                      nb::class_<SequenceResult>& sequence) {
  static const char* const kDictDoc =
      "The result as result.yaml has it (sysid/io/result.h), in plain Python objects: a dict "
      "with result.yaml's keys (status, termination, iterations, initial_cost, final_cost, "
      "parameters: [{name, value, initial, std, ci95: [low, high], flags, truth?}], warnings, "
      "fit_metrics, residuals, ...), numbers as float (NaN and infinities included), lists and "
      "dicts. json.dumps takes it. Warnings are one string each (result.yaml groups those that "
      "recur per sequence). The arrays (sequences, trace, covariance, jacobian) are result.h5's, "
      "not in the dict: see the attributes.";
  static const char* const kPandasDoc =
      "The parameters as a pandas DataFrame, one row per estimated value, indexed by name: "
      "value, initial, std, ci95_low, ci95_high, at_lower_bound, at_upper_bound, unidentifiable "
      "(result.yaml's flags as bool columns), and truth and timestep_bias when some parameter "
      "has one (NaN where not). ImportError when pandas is not installed.";
  // (nanobind keeps a docstring's pointer: these live as long as the module)
  static const std::string fit_dict_doc =
      std::string(kDictDoc) +
      " A fit of mjsysid.fit has no file: its name, experiment, created, versions, solver and "
      "identified_models are empty.";
  static const std::string experiment_dict_doc =
      std::string(kDictDoc) + " With out_dir and exit_code (not in result.yaml).";
  fit_result
      .def(
          "to_dict", [](const FitResult& r) { return DictOf(AsFile(r)); }, fit_dict_doc.c_str())
      .def(
          "to_pandas", [](const FitResult& r) { return ParametersFrame(DictOf(AsFile(r))); },
          kPandasDoc);
  result_file
      .def(
          "to_dict", [](const io::FitResultFile& r) { return DictOf(r); }, kDictDoc)
      .def(
          "to_pandas", [](const io::FitResultFile& r) { return ParametersFrame(DictOf(r)); },
          kPandasDoc);
  experiment_fit.def(
      "to_dict",
      [](const ExperimentFit& r) {
        nb::dict d = DictOf(r);
        d["out_dir"] = r.out_dir;
        d["exit_code"] = r.exit_code;
        return d;
      },
      experiment_dict_doc.c_str());
  sequence.def(
      "to_pandas",
      [](const SequenceResult& s) {
        // the channels as channel_fits names them (computed when a result has none)
        const std::vector<ChannelFit> fits =
            static_cast<Eigen::Index>(s.channel_fits.size()) == s.measured.cols() ? s.channel_fits
                                                                                  : ChannelFits(s);
        nb::list channels;
        for (const ChannelFit& f : fits) channels.append(f.channel);
        // copies: the frame owns its columns
        return Frames().attr("sequence_frame")(
            channels, Eigen::VectorXd(s.time), RowMatrix(s.measured),
            RowMatrix(s.simulated_initial), RowMatrix(s.simulated_final),
            RowMatrix(s.simulated_one_piece));
      },
      "The sequence as a pandas DataFrame, one row per sample: time, then per channel (sensor, "
      "or sensor[i] for a wider one, as channel_fits names them) measured:CHANNEL, "
      "simulated_initial:CHANNEL, simulated_final:CHANNEL and, for a fit in segments, "
      "simulated_one_piece:CHANNEL (result.h5's dataset names). ImportError when pandas is not "
      "installed.");
}

}  // namespace mjsysid::python

// Fit results: the public API (write, read, the run id checks) and the checks shared by the
// writers and readers of result.yaml and result.h5.
#include "sysid/io/result.h"

#include <hdf5.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "core/text.h"
#include "sysid/io/atomic_file.h"
#include "sysid/io/hdf5_util.h"
#include "sysid/io/result_internal.h"

namespace mjsysid::io {
namespace result_internal {

// ---------------------------------------------------------------------------------------------
// messages and numbers

// "<file>: <where>: <what>"
[[noreturn]] void Fail(const std::string& file, const std::string& where, const std::string& what) {
  throw ResultError(file + (where.empty() ? "" : ": " + where) + ": " + what);
}

// the shortest of %.15g..%.17g that reads back as x; YAML's .inf, -.inf, .nan otherwise
std::string Number(double x) { return FormatYamlNumber(x); }

// ---------------------------------------------------------------------------------------------
// checks shared by the writers and the reader

void CheckParameters(const FitResultFile& r, const std::string& file) {
  std::set<std::string> seen;
  for (size_t i = 0; i < r.parameters.size(); ++i) {
    const std::string& name = r.parameters[i].name;
    const std::string where = "parameters[" + std::to_string(i) + "]";
    if (name.empty()) Fail(file, where, "the parameter name is empty");
    if (name.find('\0') != std::string::npos) Fail(file, where, "the name contains a NUL");
    if (!seen.insert(name).second) Fail(file, where, "two parameters are named " + Quote(name));
  }
}

// a T x cols matrix of a sequence
void CheckSequenceMatrix(const RowMatrix& m, Eigen::Index rows, Eigen::Index cols,
                         const std::string& file, const std::string& object) {
  if (m.rows() != rows || m.cols() != cols) {
    Fail(file, object,
         "has shape (" + std::to_string(m.rows()) + ", " + std::to_string(m.cols()) +
             "), expected (" + std::to_string(rows) + ", " + std::to_string(cols) +
             ") = (samples in time, columns of the sensors)");
  }
}

void CheckSequence(const SequenceResult& s, const std::string& file, const std::string& where) {
  const std::string g = where + "/" + s.name;
  if (s.name.empty() || s.name == "." || s.name.find('/') != std::string::npos ||
      s.name.find('\0') != std::string::npos) {
    Fail(file, g, "sequence name " + Quote(s.name) + " is not a valid group name");
  }
  if (s.sensor_names.size() != s.sensor_dims.size()) {
    Fail(file, g,
         std::to_string(s.sensor_names.size()) + " sensor names but " +
             std::to_string(s.sensor_dims.size()) + " sensor dims");
  }
  Eigen::Index cols = 0;
  for (size_t i = 0; i < s.sensor_dims.size(); ++i) {
    if (s.sensor_dims[i] < 1) {
      Fail(file, g,
           "sensor " + Quote(s.sensor_names[i]) + " has dimension " +
               std::to_string(s.sensor_dims[i]) + " (must be >= 1)");
    }
    cols += s.sensor_dims[i];
  }
  const Eigen::Index samples = s.time.size();
  CheckSequenceMatrix(s.measured, samples, cols, file, g + "/measured");
  CheckSequenceMatrix(s.simulated_initial, samples, cols, file, g + "/simulated_initial");
  CheckSequenceMatrix(s.simulated_final, samples, cols, file, g + "/simulated_final");
  if (s.simulated_one_piece.rows() > 0) {
    CheckSequenceMatrix(s.simulated_one_piece, samples, cols, file, g + "/simulated_one_piece");
  }
}

// sizes tying the trace, covariance and jacobian to the parameters
void CheckMatrices(const FitResultFile& r, const std::string& file) {
  const auto np = static_cast<Eigen::Index>(r.parameters.size());
  const std::string nps = std::to_string(np);

  // trace: every entry holds np values, or none holds any
  const size_t width = r.trace.empty() ? 0 : r.trace[0].parameters.size();
  for (size_t i = 0; i < r.trace.size(); ++i) {
    const size_t n = r.trace[i].parameters.size();
    if (n != width || (n != 0 && n != r.parameters.size())) {
      Fail(file, "/trace/parameters",
           "trace entry " + std::to_string(i) + " holds " + std::to_string(n) +
               " parameter values, expected " + nps + " (or none in every entry)");
    }
  }

  // covariance np x np (or 0 x 0: not computed), jacobian nres x np (or 0 x 0)
  const bool cov_empty =
      r.uncertainty.covariance.rows() == 0 && r.uncertainty.covariance.cols() == 0;
  if (!cov_empty &&
      (r.uncertainty.covariance.rows() != np || r.uncertainty.covariance.cols() != np)) {
    Fail(file, "/covariance",
         "has shape (" + std::to_string(r.uncertainty.covariance.rows()) + ", " +
             std::to_string(r.uncertainty.covariance.cols()) + "), expected (" + nps + ", " + nps +
             ") for " + nps + " parameters (or (0, 0))");
  }
  const bool jac_empty = r.jacobian.rows() == 0 && r.jacobian.cols() == 0;
  if (!jac_empty && r.jacobian.cols() != np) {
    Fail(file, "/jacobian",
         "has " + std::to_string(r.jacobian.cols()) + " columns, expected " + nps +
             " (one per parameter)");
  }
}

// every check of the arrays: matrices, then sequences (valid, unique names; consistent shapes)
void CheckArrays(const FitResultFile& r, const std::string& file) {
  CheckMatrices(r, file);
  std::set<std::string> seen;
  for (const SequenceResult& s : r.sequences) {
    if (!seen.insert(s.name).second) {
      Fail(file, "/sequences/" + s.name, "two sequences are named " + Quote(s.name));
    }
    CheckSequence(s, file);
  }
  for (const SequenceResult& s : r.validation) {
    if (!seen.insert(s.name).second) {
      Fail(file, "/validation/" + s.name, "two sequences are named " + Quote(s.name));
    }
    CheckSequence(s, file, "/validation");
  }
}

}  // namespace result_internal

using namespace result_internal;  // NOLINT(build/namespaces): this file's own internals

// -----------------------------------------------------------------------------------------------

void WriteResultYaml(const std::string& path, const FitResultFile& result) {
  CheckParameters(result, path);
  const std::string text = EmitYaml(result);
  try {
    WriteFileAtomically(path, text);
  } catch (const FileError& e) {
    throw ResultError(e.what());
  }
}

namespace {

// HDF5's text of a failed system call ("... errno = 28, error message = '...' ...") as
// "<path>: cannot write: <the system's reason>"; other messages as they are
std::string WriteFailure(const std::string& path, const std::string& what) {
  const size_t at = what.find("errno = ");
  if (at == std::string::npos) return what;
  const int err = std::atoi(what.c_str() + at + 8);
  return path + ": cannot write: " + std::strerror(err);
}

}  // namespace

void WriteResultH5(const std::string& path, const FitResultFile& result) {
  CheckParameters(result, path);
  CheckMatrices(result, path);  // the sequences are checked as they are written
  std::lock_guard<std::mutex> lock(h5::Mutex());
  h5::Silence();
  try {
    ReplaceAtomically(path, [&](const std::string& tmp) { WriteH5(tmp, result, path); });
  } catch (const h5::Error& e) {
    throw ResultError(WriteFailure(path, e.what()));
  } catch (const FileError& e) {
    throw ResultError(e.what());
  }
}

std::string RunIdComment(const std::string& run_id) {
  return "<!-- mjsysid run " + run_id + " -->";
}

FitResultFile ReadResultFiles(const std::string& yaml_path, const std::string& h5_path) {
  FitResultFile r;
  ReadYaml(yaml_path, &r);
  std::string h5_run;
  try {
    ReadH5(h5_path, &r, &h5_run);
  } catch (const h5::Error& e) {
    throw ResultError(e.what());
  }
  const auto show = [](const std::string& id) { return id.empty() ? "none" : id; };
  if (h5_run != r.run_id) {
    throw ResultError(std::filesystem::path(yaml_path).parent_path().string() +
                      ": the files come from different fits: " +
                      std::filesystem::path(yaml_path).filename().string() + " is run " +
                      show(r.run_id) + ", " + std::filesystem::path(h5_path).filename().string() +
                      " is run " + show(h5_run) + " (run `sysid fit` again into this folder)");
  }
  return r;
}

FitResultFile ReadResult(const std::string& dir) {
  const std::filesystem::path d(dir);
  FitResultFile r = ReadResultFiles((d / "result.yaml").string(), (d / "result.h5").string());

  // one run: every identified model carries result.yaml's run id
  for (const auto& [model, file] : r.identified_models) {
    if (r.run_id.empty()) break;  // a result of an older version, or built by hand
    const std::string path = (d / file).string();
    std::ifstream in(path, std::ios::binary);
    if (!in) throw ResultError(path + ": missing (result.yaml lists it as model " + model + ")");
    std::string head(4096, '\0');
    in.read(head.data(), static_cast<std::streamsize>(head.size()));
    head.resize(static_cast<size_t>(in.gcount()));
    if (head.find(RunIdComment(r.run_id)) == std::string::npos) {
      throw ResultError(dir + ": the files come from different fits: " + file +
                        " is not from run " + r.run_id + " of result.yaml (run `sysid fit` " +
                        "again into this folder)");
    }
  }
  return r;
}

}  // namespace mjsysid::io

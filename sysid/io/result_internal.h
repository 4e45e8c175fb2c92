// Internal to sysid/io/result*.cc: the format's constants, the checks shared by the writers and
// the readers (result.cc), and the writers and readers of result.yaml (result_yaml_write.cc,
// result_yaml_read.cc) and result.h5 (result_h5.cc), whose fields result_fields.h lists. Each
// throws ResultError "<file>: <where>: <what>".
#pragma once

#include <hdf5.h>

#include <string>

#include "sysid/io/result.h"

namespace mjsysid::io::result_internal {

inline constexpr char kFormat[] = "mjsysid-result";
inline constexpr int kFormatVersion = 1;
inline constexpr const char* kTraceColumns[] = {"iteration",     "cost",    "step_norm",
                                                "gradient_norm", "seconds", "successful"};

// "<file>: <where>: <what>"
[[noreturn]] void Fail(const std::string& file, const std::string& where, const std::string& what);
// the shortest of %.15g..%.17g that reads back as x; YAML's .inf, -.inf, .nan otherwise
std::string Number(double x);

// the parameter names (unique, non-empty); a sequence's matrices against its sizes; the trace,
// covariance and jacobian against the parameters; all of them
void CheckParameters(const FitResultFile& r, const std::string& file);
void CheckSequenceMatrix(const RowMatrix& m, Eigen::Index rows, Eigen::Index cols,
                         const std::string& file, const std::string& object);
// where: the group the sequence is stored in ("/sequences", or "/validation" for held-out ones)
void CheckSequence(const SequenceResult& s, const std::string& file,
                   const std::string& where = "/sequences");
void CheckMatrices(const FitResultFile& r, const std::string& file);
void CheckArrays(const FitResultFile& r, const std::string& file);

// result.yaml's text, and result.yaml read from path (the checks of CheckParameters included)
std::string EmitYaml(const FitResultFile& r);
void ReadYaml(const std::string& path, FitResultFile* r);

// result.h5 written to tmp (messages name file), and read back (with its run id)
void WriteH5(const std::string& tmp, const FitResultFile& r, const std::string& file);
void ReadH5(const std::string& path, FitResultFile* r, std::string* run_id);

}  // namespace mjsysid::io::result_internal

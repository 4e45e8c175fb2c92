#include "sysid/io/csv.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "core/text.h"

namespace mjsysid::io {
namespace {

// what a column feeds
enum class Kind { kTime, kCtrl, kSensor, kQpos, kQvel, kAct };

struct Target {
  Kind kind;
  int index;      // actuator, sensor or state index
  int component;  // sensor component
};

[[noreturn]] void Fail(const std::string& file, const std::string& what) {
  throw LogError(file + ": " + what);
}

std::string Indexed(const std::string& base, int i) { return base + "[" + std::to_string(i) + "]"; }

// "name[0..n-1]" (or "name[0]") for hints
std::string Range(const std::string& base, int n) {
  return n == 1 ? Indexed(base, 0) : base + "[0.." + std::to_string(n - 1) + "]";
}

// the columns a model accepts, every name with what it feeds (several targets: ambiguous)
struct Columns {
  std::map<std::string, std::vector<Target>> targets;
  std::vector<std::string> names;    // every valid header, for "did you mean"
  std::vector<std::string> summary;  // compact list for the hint
};

Columns ModelColumns(const mjModel& m) {
  Columns c;
  auto add = [&c](const std::string& name, Target t) {
    c.targets[name].push_back(t);
    c.names.push_back(name);
  };
  add("time", {Kind::kTime, 0, 0});
  c.summary.push_back("time");
  for (int i = 0; i < static_cast<int>(m.nu); ++i) {
    const char* n = mj_id2name(&m, mjOBJ_ACTUATOR, i);
    if (!n) continue;
    add(n, {Kind::kCtrl, i, 0});
    c.summary.push_back(n);
  }
  for (int s = 0; s < static_cast<int>(m.nsensor); ++s) {
    const char* n = mj_id2name(&m, mjOBJ_SENSOR, s);
    if (!n) continue;
    const int dim = m.sensor_dim[s];
    if (dim == 1) {
      add(n, {Kind::kSensor, s, 0});
      c.summary.push_back(n);
    } else {
      for (int j = 0; j < dim; ++j) add(Indexed(n, j), {Kind::kSensor, s, j});
      c.summary.push_back(Range(n, dim));
    }
  }
  const std::tuple<const char*, Kind, int> states[] = {
      {"qpos", Kind::kQpos, static_cast<int>(m.nq)},
      {"qvel", Kind::kQvel, static_cast<int>(m.nv)},
      {"act", Kind::kAct, static_cast<int>(m.na)}};
  for (const auto& [base, kind, n] : states) {
    for (int j = 0; j < n; ++j) add(Indexed(base, j), {kind, j, 0});
    if (n > 0) c.summary.push_back(Range(base, n));
  }
  return c;
}

std::string Trim(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  const size_t e = s.find_last_not_of(" \t");
  return s.substr(b, e - b + 1);
}

// one line into trimmed fields; quoted fields keep their inner spaces
std::vector<std::string> SplitLine(const std::string& line, const std::string& where) {
  std::vector<std::string> fields;
  std::string field;
  bool quoted = false;      // inside quotes
  bool was_quoted = false;  // this field was quoted: keep it as it is
  size_t i = 0;
  while (i <= line.size()) {
    const char ch = i < line.size() ? line[i] : ',';
    if (quoted) {
      if (i == line.size()) Fail(where, "unterminated quote");
      if (ch == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        field += '"';
        ++i;
      } else if (ch == '"') {
        quoted = false;
      } else {
        field += ch;
      }
    } else if (ch == ',') {
      fields.push_back(was_quoted ? field : Trim(field));
      field.clear();
      was_quoted = false;
    } else if (ch == '"' && Trim(field).empty()) {
      quoted = true;
      was_quoted = true;
      field.clear();
    } else if (!(was_quoted && (ch == ' ' || ch == '\t'))) {
      field += ch;
    }
    ++i;
  }
  return fields;
}

// a whole field as a finite double
double ParseNumber(const std::string& text, const std::string& where) {
  if (text.empty()) Fail(where, "empty cell (expected a number)");
  const char* begin = text.data();
  const char* end = text.data() + text.size();
  if (*begin == '+') ++begin;
  double value = 0;
  const auto [ptr, ec] = std::from_chars(begin, end, value);
  if (ec == std::errc::result_out_of_range) Fail(where, Quote(text) + " is out of range");
  if (ec != std::errc() || ptr != end) Fail(where, Quote(text) + " is not a number");
  if (!std::isfinite(value)) Fail(where, "value " + Quote(text) + " is not finite (NaN/Inf)");
  if (std::abs(value) > kLargestLoggedMagnitude) {
    Fail(where, "value " + Quote(text) + " is beyond +-" + FormatShortest(kLargestLoggedMagnitude) +
                    ", where its square overflows the simulation and the cost (a unit or "
                    "conversion error?)");
  }
  return value;
}

// a sensor or control cell: empty or NaN (any case) is NaN, a value not measured; else a finite
// double
double ParseNumberOrMissing(const std::string& text, const std::string& where) {
  if (text.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::string lower = text;
  for (char& ch : lower) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  if (lower == "nan") return std::numeric_limits<double>::quiet_NaN();
  return ParseNumber(text, where);
}

// Refuses what is not a comma-separated UTF-8/ASCII text with LF or CRLF line ends, from the
// first 64 KiB: UTF-16/32 (byte order mark or NUL bytes), other NUL bytes, CR-only line ends;
// rewinds `in`
void CheckEncoding(std::ifstream& in, const std::string& file) {
  std::string head(64 * 1024, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<size_t>(in.gcount()));
  in.clear();
  in.seekg(0);
  const std::string hint = ": save it as a UTF-8 (or ASCII) CSV with comma separators";
  if (head.rfind("\xFF\xFE", 0) == 0 || head.rfind("\xFE\xFF", 0) == 0) {
    Fail(file, "is UTF-16 or UTF-32 encoded (byte order mark " +
                   std::string(head[0] == '\xFF' ? "FF FE" : "FE FF") + ")" + hint);
  }
  const size_t nul = head.find('\0');
  if (nul != std::string::npos) {
    Fail(file, "contains a NUL byte at byte " + std::to_string(nul) +
                   " (UTF-16 without a byte order mark, or not a text file)" + hint);
  }
  if (head.find('\n') == std::string::npos && head.find('\r') != std::string::npos) {
    Fail(file, "has CR-only line ends (classic Mac OS): convert them to LF or CRLF");
  }
}

// One file: ImportCsv's reading. part: one of several files of a sequence (ImportCsvFiles): the
// actuator columns are all there or none (*has_ctrl says which; ctrl is then T x 0)
Sequence ReadCsv(const std::string& path, const mjModel& m, const std::string& sequence_name,
                 bool part, bool* has_ctrl);

}  // namespace

Sequence ImportCsv(const std::string& path, const mjModel& m, const std::string& sequence_name) {
  bool has_ctrl = false;
  return ReadCsv(path, m, sequence_name, false, &has_ctrl);
}

namespace {

// a group name mjsysid can store the sequence under (the log's rule, checked before any reading)
void CheckSequenceName(const std::string& file, const std::string& sequence_name) {
  if (sequence_name.empty() || sequence_name == "." ||
      sequence_name.find('/') != std::string::npos) {
    Fail(file, "sequence name " + Quote(sequence_name) +
                   " is not a valid group name (non-empty, no '/', not '.')");
  }
}

// the file's non-blank lines, CR of CRLF and a leading UTF-8 byte order mark removed, with their
// 1-based line numbers (blank lines count, so messages match an editor's numbering)
class LineReader {
 public:
  explicit LineReader(std::ifstream& in) : in_(in) {}

  bool Next() {
    while (std::getline(in_, line_)) {
      ++line_no_;
      if (!line_.empty() && line_.back() == '\r') line_.pop_back();
      if (line_no_ == 1 && line_.rfind("\xEF\xBB\xBF", 0) == 0) line_.erase(0, 3);
      if (!Trim(line_).empty()) return true;
    }
    return false;
  }
  const std::string& line() const { return line_; }
  int line_no() const { return line_no_; }

 private:
  std::ifstream& in_;
  std::string line_;
  int line_no_ = 0;
};

// the header row and where it is ("<file>:<line>"), for every message about columns
struct Header {
  std::vector<std::string> names;
  std::string where;
};

// the first non-blank line as the header; a ';'-separated one is refused with a hint, since it
// would otherwise be read as one unknown column
Header ReadHeader(LineReader& lines, const std::string& file) {
  if (!lines.Next()) Fail(file, "empty file (no header line)");
  Header h;
  h.where = file + ":" + std::to_string(lines.line_no());
  h.names = SplitLine(lines.line(), h.where);
  if (h.names.size() == 1 && lines.line().find(';') != std::string::npos) {
    Fail(h.where,
         "the header has ';' separators and no ',': a CSV of a locale with decimal commas? "
         "(hint: export it with ',' separators and '.' decimals)");
  }
  return h;
}

// each header to what it feeds in the model: unknown, duplicate, empty and ambiguous names fail
// at their column, unknown ones with the model's valid names as a hint
std::vector<Target> MapColumns(const Header& header, const mjModel& m) {
  const Columns columns = ModelColumns(m);
  std::vector<Target> targets;
  std::map<std::string, int> seen;
  for (size_t c = 0; c < header.names.size(); ++c) {
    const std::string& h = header.names[c];
    const std::string where =
        header.where + ": column " + std::to_string(c + 1) + " (" + Quote(h) + ")";
    if (h.empty()) Fail(where, "empty column header");
    if (!seen.emplace(h, static_cast<int>(c + 1)).second) {
      Fail(where, "duplicate column (also column " + std::to_string(seen[h]) + ")");
    }
    auto it = columns.targets.find(h);
    if (it == columns.targets.end()) {
      std::string hint = internal::NameHint(h, columns.names, "valid columns");
      // the compact list reads better than every component
      hint = hint.substr(0, hint.find("; valid columns: ")) + "; valid columns: ";
      for (size_t i = 0; i < columns.summary.size() && i < 20; ++i) {
        hint += (i ? ", " : "") + columns.summary[i];
      }
      if (columns.summary.size() > 20) hint += ", ...";
      Fail(where, "unknown column " + hint);
    }
    if (it->second.size() > 1) {
      Fail(where,
           "ambiguous column: the model has more than one object (actuator, sensor) by "
           "that name");
    }
    targets.push_back(it->second[0]);
  }
  return targets;
}

// where each model quantity is in the file (-1: absent), and which sensors are present
struct ColumnPlan {
  int time_col = -1;
  std::vector<int> ctrl_col;                   // per actuator
  std::vector<std::vector<int>> sensor_col;    // per sensor and component
  std::map<Kind, std::vector<int>> state_col;  // per qpos, qvel, act component
  std::vector<int> sensors;                    // present sensors, model order
};

// the file column of every model quantity, from the columns' targets
ColumnPlan IndexColumns(const std::vector<Target>& targets, const mjModel& m) {
  ColumnPlan p;
  p.ctrl_col.assign(m.nu, -1);
  p.sensor_col.resize(m.nsensor);
  for (int s = 0; s < m.nsensor; ++s) p.sensor_col[s].assign(m.sensor_dim[s], -1);
  p.state_col = {{Kind::kQpos, std::vector<int>(m.nq, -1)},
                 {Kind::kQvel, std::vector<int>(m.nv, -1)},
                 {Kind::kAct, std::vector<int>(m.na, -1)}};
  for (size_t c = 0; c < targets.size(); ++c) {
    const Target& t = targets[c];
    const int col = static_cast<int>(c);
    switch (t.kind) {
      case Kind::kTime:
        p.time_col = col;
        break;
      case Kind::kCtrl:
        p.ctrl_col[t.index] = col;
        break;
      case Kind::kSensor:
        p.sensor_col[t.index][t.component] = col;
        break;
      default:
        p.state_col[t.kind][t.index] = col;
    }
  }
  return p;
}

// the required and all-or-nothing columns: time; every actuator (of a part: all or none, which
// *has_ctrl reports); every component of a sensor or state given at all; fills plan->sensors
void CheckColumns(const mjModel& m, const std::string& header_where, bool part, bool* has_ctrl,
                  ColumnPlan* plan) {
  if (plan->time_col < 0) Fail(header_where, "missing column 'time' (seconds)");
  const int nu = static_cast<int>(m.nu);
  int ctrl_given = 0;
  for (int col : plan->ctrl_col) ctrl_given += col >= 0 ? 1 : 0;
  *has_ctrl = ctrl_given > 0 || !part;
  for (int i = 0; i < nu && *has_ctrl; ++i) {
    if (plan->ctrl_col[i] >= 0) continue;
    const char* n = mj_id2name(&m, mjOBJ_ACTUATOR, i);
    Fail(header_where, n ? "missing actuator column " + Quote(n) +
                               " (every actuator of the model needs a ctrl column)"
                         : "actuator " + std::to_string(i) +
                               " of the model has no name, so no column can hold its control");
  }
  for (int s = 0; s < static_cast<int>(m.nsensor); ++s) {
    int given = 0;
    for (int col : plan->sensor_col[s]) given += col >= 0;
    if (given == 0) continue;
    const std::string name = mj_id2name(&m, mjOBJ_SENSOR, s);
    for (int j = 0; j < m.sensor_dim[s]; ++j) {
      if (plan->sensor_col[s][j] < 0) {
        Fail(header_where, "sensor " + Quote(name) + " has " + std::to_string(m.sensor_dim[s]) +
                               " components but column " + Quote(Indexed(name, j)) +
                               " is missing (give all of them or none)");
      }
    }
    plan->sensors.push_back(s);
  }
  const std::pair<Kind, const char*> state_names[] = {
      {Kind::kQpos, "qpos"}, {Kind::kQvel, "qvel"}, {Kind::kAct, "act"}};
  for (const auto& [kind, base] : state_names) {
    const std::vector<int>& cols = plan->state_col[kind];
    int given = 0;
    for (int col : cols) given += col >= 0;
    for (size_t j = 0; given > 0 && j < cols.size(); ++j) {
      if (cols[j] < 0) {
        Fail(header_where, "column " + Quote(Indexed(base, static_cast<int>(j))) + " is missing (" +
                               base + " needs all " + std::to_string(cols.size()) +
                               " components or none)");
      }
    }
  }
}

// the data rows as numbers, row-major in file column order, and each row's line number
struct Rows {
  size_t ncols = 0;
  std::vector<double> values;
  std::vector<int> lines;
  double at(Eigen::Index k, int col) const { return values[k * ncols + col]; }
};

// every line after the header, each with the header's number of fields; an empty or NaN cell of
// a sensor or control is a value not measured (NaN), any other cell must be a finite number
Rows ReadRows(LineReader& lines, std::ifstream& in, const Header& header,
              const std::vector<Target>& targets, const std::string& file) {
  Rows rows;
  rows.ncols = header.names.size();
  const size_t ncols = rows.ncols;
  while (lines.Next()) {
    const std::string where_line = file + ":" + std::to_string(lines.line_no());
    const std::vector<std::string> fields = SplitLine(lines.line(), where_line);
    if (fields.size() != ncols) {
      Fail(where_line, std::to_string(fields.size()) + " fields, the header (line " +
                           header.where.substr(file.size() + 1) + ") has " + std::to_string(ncols) +
                           (fields.size() > ncols ? " (decimal commas? numbers need a '.')" : ""));
    }
    for (size_t c = 0; c < ncols; ++c) {
      // sensors and controls: an empty cell or NaN is a value not measured (NaN)
      const bool may_miss = targets[c].kind == Kind::kSensor || targets[c].kind == Kind::kCtrl;
      const std::string where =
          where_line + ": column " + std::to_string(c + 1) + " (" + Quote(header.names[c]) + ")";
      rows.values.push_back(may_miss ? ParseNumberOrMissing(fields[c], where)
                                     : ParseNumber(fields[c], where));
    }
    rows.lines.push_back(lines.line_no());
  }
  if (in.bad()) Fail(file, "read error");
  if (rows.lines.empty()) Fail(file, "no data rows after the header");
  return rows;
}

// the sequence from the rows: time (strictly increasing, checked here with both lines named),
// ctrl in actuator order (T x 0 without controls), the present sensors in model order, the
// states that were given
Sequence Assemble(const Rows& rows, const ColumnPlan& plan, const mjModel& m,
                  const std::string& sequence_name, bool has_ctrl, const std::string& file) {
  const auto samples = static_cast<Eigen::Index>(rows.lines.size());
  const int nu = static_cast<int>(m.nu);
  Sequence seq;
  seq.name = sequence_name;
  seq.time.resize(samples);
  for (Eigen::Index k = 0; k < samples; ++k) {
    seq.time[k] = rows.at(k, plan.time_col);
    if (k > 0 && !(seq.time[k] > seq.time[k - 1])) {
      Fail(file + ":" + std::to_string(rows.lines[k]),
           "column " + std::to_string(plan.time_col + 1) + " ('time'): time " +
               FormatG17(seq.time[k]) + " is not greater than " + FormatG17(seq.time[k - 1]) +
               " on line " + std::to_string(rows.lines[k - 1]) +
               " (time must be strictly increasing)");
    }
  }
  seq.ctrl.resize(samples, has_ctrl ? nu : 0);
  for (int i = 0; i < nu && has_ctrl; ++i) {
    seq.actuator_names.push_back(mj_id2name(&m, mjOBJ_ACTUATOR, i));
    for (Eigen::Index k = 0; k < samples; ++k) seq.ctrl(k, i) = rows.at(k, plan.ctrl_col[i]);
  }
  int width = 0;
  for (int s : plan.sensors) width += m.sensor_dim[s];
  seq.sensordata.resize(samples, width);
  int offset = 0;
  for (int s : plan.sensors) {
    seq.sensor_names.push_back(mj_id2name(&m, mjOBJ_SENSOR, s));
    seq.sensor_dims.push_back(m.sensor_dim[s]);
    for (int j = 0; j < m.sensor_dim[s]; ++j) {
      for (Eigen::Index k = 0; k < samples; ++k) {
        seq.sensordata(k, offset + j) = rows.at(k, plan.sensor_col[s][j]);
      }
    }
    offset += m.sensor_dim[s];
  }
  const std::pair<Kind, RowMatrix*> state_out[] = {
      {Kind::kQpos, &seq.qpos}, {Kind::kQvel, &seq.qvel}, {Kind::kAct, &seq.act}};
  for (const auto& [kind, mat] : state_out) {
    const std::vector<int>& cols = plan.state_col.at(kind);
    if (cols.empty() || cols[0] < 0) continue;
    mat->resize(samples, static_cast<Eigen::Index>(cols.size()));
    for (size_t j = 0; j < cols.size(); ++j) {
      for (Eigen::Index k = 0; k < samples; ++k) {
        (*mat)(k, static_cast<Eigen::Index>(j)) = rows.at(k, cols[j]);
      }
    }
  }
  return seq;
}

Sequence ReadCsv(const std::string& path, const mjModel& m, const std::string& sequence_name,
                 bool part, bool* has_ctrl) {
  const std::string& file = path;
  // the name first: nothing is read for a sequence that could not be stored
  CheckSequenceName(file, sequence_name);
  // open the file and refuse what is not comma-separated UTF-8/ASCII text
  std::ifstream in(path, std::ios::binary);
  if (!in) Fail(file, std::string("cannot open: ") + std::strerror(errno));
  CheckEncoding(in, file);
  // the header, each of its names mapped to the model, then the columns the model requires
  LineReader lines(in);
  const Header header = ReadHeader(lines, file);
  const std::vector<Target> targets = MapColumns(header, m);
  ColumnPlan plan = IndexColumns(targets, m);
  CheckColumns(m, header.where, part, has_ctrl, &plan);
  // the numbers, then the sequence in the model's order
  const Rows rows = ReadRows(lines, in, header, targets, file);
  return Assemble(rows, plan, m, sequence_name, *has_ctrl, file);
}

}  // namespace

// Several files of one sequence: the controls from the one file with actuator columns (their
// times become ctrl_time), every sensor from the one file that has it; the sample times are the
// union of the times of the files with sensors (equal times merged), each sensor NaN (not
// measured) at the times its file has no row
Sequence ImportCsvFiles(const std::vector<std::string>& paths, const mjModel& m,
                        const std::string& sequence_name) {
  if (paths.size() == 1) return ImportCsv(paths[0], m, sequence_name);
  std::vector<Sequence> parts;
  int ctrl_part = -1;
  std::map<std::string, size_t> sensor_file;  // sensor -> the part holding it
  for (size_t f = 0; f < paths.size(); ++f) {
    bool has_ctrl = false;
    parts.push_back(ReadCsv(paths[f], m, sequence_name, true, &has_ctrl));
    const Sequence& p = parts.back();
    if (has_ctrl && m.nu > 0) {
      if (ctrl_part >= 0) {
        Fail(paths[f], "has actuator columns, and so has " + paths[ctrl_part] +
                           ": the controls of a sequence come from one file");
      }
      ctrl_part = static_cast<int>(f);
    }
    if (p.qpos.size() || p.qvel.size() || p.act.size()) {
      Fail(paths[f],
           "has state columns (qpos, qvel, act): a sequence of several files cannot "
           "hold states (a state needs a value at every sample time); import the "
           "states' file alone");
    }
    for (const std::string& name : p.sensor_names) {
      const auto [it, added] = sensor_file.emplace(name, f);
      if (!added) {
        Fail(paths[f], "sensor " + Quote(name) + " is in " + paths[it->second] +
                           " too: each sensor comes from one file");
      }
    }
  }
  if (ctrl_part < 0 && m.nu > 0) {
    Fail(paths[0], "none of the " + std::to_string(paths.size()) + " files of sequence " +
                       Quote(sequence_name) +
                       " has the actuator columns (one file must hold every actuator's control)");
  }
  if (sensor_file.empty()) {
    Fail(paths[0],
         "none of the files of sequence " + Quote(sequence_name) + " has a sensor column");
  }

  // sample times: the union of the times of the files with sensors
  std::vector<double> times;
  for (const Sequence& p : parts) {
    if (p.sensor_names.empty()) continue;
    times.insert(times.end(), p.time.data(), p.time.data() + p.time.size());
  }
  std::sort(times.begin(), times.end());
  times.erase(std::unique(times.begin(), times.end()), times.end());
  const auto T = static_cast<Eigen::Index>(times.size());

  Sequence seq;
  seq.name = sequence_name;
  seq.time = Eigen::Map<const Eigen::VectorXd>(times.data(), T);
  if (ctrl_part >= 0) {
    seq.ctrl = parts[ctrl_part].ctrl;
    seq.ctrl_time = parts[ctrl_part].time;
    seq.actuator_names = parts[ctrl_part].actuator_names;
  } else {
    seq.ctrl.resize(T, 0);
  }
  // sensors in model order, each at its file's times
  auto sensor_name = [&](int s) {  // "" for an unnamed sensor (no column can hold it)
    const char* name = mj_id2name(&m, mjOBJ_SENSOR, s);
    return std::string(name ? name : "");
  };
  int width = 0;
  for (int s = 0; s < m.nsensor; ++s) {
    if (sensor_file.count(sensor_name(s))) width += m.sensor_dim[s];
  }
  seq.sensordata = RowMatrix::Constant(T, width, std::numeric_limits<double>::quiet_NaN());
  int offset = 0;
  for (int s = 0; s < m.nsensor; ++s) {
    const std::string name = sensor_name(s);
    const auto it = sensor_file.find(name);
    if (it == sensor_file.end()) continue;
    const Sequence& p = parts[it->second];
    int col = 0;  // the sensor's first column in its file's sensordata
    for (size_t i = 0; p.sensor_names[i] != name; ++i) col += p.sensor_dims[i];
    Eigen::Index k = 0;
    for (Eigen::Index r = 0; r < p.time.size(); ++r) {
      while (times[k] < p.time[r]) ++k;  // p's times are a subset of `times`
      for (int j = 0; j < m.sensor_dim[s]; ++j)
        seq.sensordata(k, offset + j) = p.sensordata(r, col + j);
    }
    seq.sensor_names.push_back(name);
    seq.sensor_dims.push_back(m.sensor_dim[s]);
    offset += m.sensor_dim[s];
  }
  return seq;
}

}  // namespace mjsysid::io

// bench_fit's outputs: the table on stdout, the ratios of ours to the best peer, and the CSV,
// Markdown, JSON and SVG files (tools/bench/run_fit_benchmarks.sh and BENCHMARKS.md read them).
#include <ceres/ceres.h>
#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "mjsysid/version.h"
#include "sysid/io/atomic_file.h"
#include "tools/bench/fit_bench.h"

namespace mjsysid {
namespace bench {

std::string Num(double v, const char* fmt) {
  if (std::isnan(v)) return "";
  char buf[64];
  std::snprintf(buf, sizeof(buf), fmt, v);
  return buf;
}

void PrintHeader() {
  std::printf("%-16s %-28s %2s %-10s %9s %5s %12s %11s %11s %10s %8s %8s  %s\n", "case", "method",
              "th", "status", "wall [s]", "iter", "sim steps", "final cost", "max rel err",
              "rms rel", "/floor", "/path", "note");
}

void PrintRow(const Row& r) {
  std::printf("%-16s %-28s %2d %-10s %9s %5d %12lld %11s %11s %10s %8s %8s  %s\n",
              r.case_name.c_str(), r.method.c_str(), r.threads, r.status.c_str(),
              Num(r.wall_s, "%.3f").c_str(), r.iterations, r.steps,
              Num(r.final_cost, "%.6g").c_str(), Num(r.max_rel_error, "%.2e").c_str(),
              Num(r.rms_rel_error, "%.2e").c_str(), Num(r.floor_ratio, "%.2f").c_str(),
              Num(r.path_floor_ratio, "%.2f").c_str(), r.note.c_str());
  std::fflush(stdout);
}

namespace {

bool Finished(const Row& r) { return std::isfinite(r.wall_s) && r.iterations > 0; }
bool IsOurs(const Row& r) { return r.method.rfind("ours/", 0) == 0; }
bool IsPeer(const Row& r) {
  return r.method.rfind("ceres-numdiff", 0) == 0 || r.method.rfind("mujoco.sysid", 0) == 0;
}

}  // namespace

std::vector<Ratio> Ratios(const std::vector<std::string>& cases, const std::vector<Row>& rows,
                          bool own_start) {
  std::vector<Ratio> out;
  for (const std::string& name : cases) {
    int fewest = 0;
    for (const Row& r : rows) {
      if (r.case_name == name && IsPeer(r) && Finished(r)) {
        fewest = fewest ? std::min(fewest, r.iterations) : r.iterations;
      }
    }
    for (int threads : {1, 2}) {
      Ratio q;
      q.case_name = name;
      q.own_start = own_start;
      q.threads = threads;
      q.peer_fewest_iterations = fewest;
      for (const Row& r : rows) {
        if (r.case_name != name || r.threads != threads || !Finished(r)) continue;
        const bool eligible =
            IsOurs(r) && !(own_start && r.method.find("+auto") != std::string::npos);
        if (eligible && (!q.ours || r.wall_s < q.ours->wall_s)) q.ours = &r;
        if (IsPeer(r) && (!q.peer || r.wall_s < q.peer->wall_s)) q.peer = &r;
      }
      if (q.ours && q.peer) q.speedup = q.peer->wall_s / q.ours->wall_s;
      if (q.ours) out.push_back(q);
    }
  }
  return out;
}

std::string RatioLine(const Ratio& q, const char* sep) {
  std::ostringstream f;
  f << q.case_name << sep << q.threads << sep << q.ours->method << sep
    << Num(q.ours->wall_s, "%.3f") << sep << q.ours->iterations << sep
    << (q.peer ? q.peer->method : std::string("n/a")) << sep
    << (q.peer ? Num(q.peer->wall_s, "%.3f") : "") << sep << Num(q.speedup, "%.2f") << sep
    << (q.peer_fewest_iterations ? std::to_string(q.peer_fewest_iterations) : "") << sep
    << (q.ours->idle && (!q.peer || q.peer->idle) ? "" : "not idle");
  return f.str();
}

void WriteCsv(const std::string& path, const std::vector<Row>& rows) {
  std::ostringstream f;
  f << "case,method,threads,status,wall_s,iterations,sim_steps,np,sequences,samples,t_step_us,"
       "floor_ratio,initial_cost,final_cost,max_rel_error,rms_rel_error,note,others_cores,load1,"
       "idle,path_t_step_us,path_floor_ratio,host_slowness,attempts\n";
  for (const Row& r : rows) {
    std::string note = r.note;
    std::replace(note.begin(), note.end(), ',', ';');
    std::replace(note.begin(), note.end(), '\n', ' ');
    f << r.case_name << ',' << r.method << ',' << r.threads << ',' << r.status << ','
      << Num(r.wall_s) << ',' << r.iterations << ',' << r.steps << ',' << r.np << ',' << r.sequences
      << ',' << r.samples << ',' << Num(r.t_step_us) << ',' << Num(r.floor_ratio) << ','
      << Num(r.initial_cost, "%.10g") << ',' << Num(r.final_cost, "%.10g") << ','
      << Num(r.max_rel_error) << ',' << Num(r.rms_rel_error) << ',' << note << ','
      << Num(r.others_cores, "%.3f") << ',' << Num(r.load1, "%.2f") << ',' << (r.idle ? 1 : 0)
      << ',' << Num(r.path_t_step_us) << ',' << Num(r.path_floor_ratio) << ','
      << Num(r.host_slowness, "%.3f") << ',' << r.attempts << '\n';
  }
  io::WriteFileAtomically(path, f.str());
}

void WriteMarkdown(const std::string& path, const std::vector<Row>& rows,
                   const std::vector<Ratio>& ratios) {
  std::ostringstream f;
  f << "| case | method | threads | status | wall [s] | iterations | sim steps | final cost | "
       "max rel. error | time/iteration / floor | / path floor | note |\n"
    << "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n";
  for (const Row& r : rows) {
    f << "| " << r.case_name << " | " << r.method << " | " << r.threads << " | " << r.status
      << " | " << Num(r.wall_s, "%.3f") << " | " << r.iterations << " | " << r.steps << " | "
      << Num(r.final_cost, "%.6g") << " | " << Num(r.max_rel_error, "%.2e") << " | "
      << Num(r.floor_ratio, "%.2f") << " | " << Num(r.path_floor_ratio, "%.2f") << " | " << r.note
      << " |\n";
  }
  for (const bool own : {false, true}) {
    f << "\nOurs" << (own ? " from the experiment's own starts" : "")
      << " against the best peer at equal threads (speed-up = peer wall / our wall):\n\n"
      << "| case | threads | ours (fastest) | wall [s] | iterations | best peer | wall [s] | "
         "speed-up | peer's fewest iterations | load |\n"
      << "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n";
    for (const Ratio& q : ratios) {
      if (q.own_start == own) f << "| " << RatioLine(q, " | ") << " |\n";
    }
  }
  io::WriteFileAtomically(path, f.str());
}

void WriteJson(const std::string& path, const std::vector<Row>& rows,
               const std::vector<Ratio>& ratios, const std::string& command) {
  char date[32];
  const std::time_t now = std::time(nullptr);
  std::strftime(date, sizeof(date), "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&now));
  nlohmann::ordered_json j;
  j["tool"] = "bench_fit";
  j["created"] = date;
  j["command"] = command;
  j["machine"] = {{"cpu", Machine()}, {"hardware_threads", std::thread::hardware_concurrency()}};
  j["versions"] = {{"mjsysid", MJSYSID_VERSION},
                   {"mujoco", mj_versionString()},
                   {"ceres", CERES_VERSION_STRING},
                   {"compiler", MJSYSID_COMPILER},
                   {"build_type", MJSYSID_BUILD_TYPE}};
  j["rows"] = nlohmann::ordered_json::array();
  for (const Row& r : rows) {
    nlohmann::ordered_json estimates = nlohmann::ordered_json::object();
    for (const auto& [name, value] : r.estimates) estimates[name] = value;
    j["rows"].push_back({{"case", r.case_name},
                         {"method", r.method},
                         {"threads", r.threads},
                         {"status", r.status},
                         {"wall_s", r.wall_s},
                         {"iterations", r.iterations},
                         {"sim_steps", r.steps},
                         {"np", r.np},
                         {"sequences", r.sequences},
                         {"samples", r.samples},
                         {"t_step_us", r.t_step_us},
                         {"floor_ratio", r.floor_ratio},
                         {"path_t_step_us", r.path_t_step_us},
                         {"path_floor_ratio", r.path_floor_ratio},
                         {"initial_cost", r.initial_cost},
                         {"final_cost", r.final_cost},
                         {"max_rel_error", r.max_rel_error},
                         {"rms_rel_error", r.rms_rel_error},
                         {"note", r.note},
                         {"others_cores", r.others_cores},
                         {"load1", r.load1},
                         {"idle", r.idle},
                         {"runs", r.runs},
                         {"host_slowness", r.host_slowness},
                         {"attempts", r.attempts},
                         {"estimates", estimates}});
  }
  j["ratios"] = nlohmann::ordered_json::array();
  for (const Ratio& q : ratios) {
    j["ratios"].push_back({{"case", q.case_name},
                           {"own_start", q.own_start},
                           {"threads", q.threads},
                           {"ours", q.ours->method},
                           {"ours_wall_s", q.ours->wall_s},
                           {"ours_iterations", q.ours->iterations},
                           {"peer", q.peer ? q.peer->method : ""},
                           {"peer_wall_s", q.peer ? q.peer->wall_s : NAN},
                           {"speedup", q.speedup},
                           {"peer_fewest_iterations", q.peer_fewest_iterations}});
  }
  io::WriteFileAtomically(path, j.dump(2) + "\n");
}

// error against time, one log-log panel per case; a point per method that finished
void WriteSvg(const std::string& path, const std::vector<std::string>& cases,
              const std::vector<Row>& rows) {
  const int cols = 2, pw = 520, ph = 300, ml = 70, mb = 40, mt = 30, mr = 190;
  const int nrows = (static_cast<int>(cases.size()) + cols - 1) / cols;
  std::ostringstream f;
  f << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << cols * pw << "\" height=\""
    << nrows * ph << "\" font-family=\"sans-serif\" font-size=\"10\">\n"
    << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  auto color = [](const std::string& m) {
    if (m.rfind("ours/directional", 0) == 0) return "#1f77b4";
    if (m.rfind("ours/matrix", 0) == 0) return "#2ca02c";
    if (m.rfind("oracle", 0) == 0) return "#9467bd";
    if (m.rfind("ceres", 0) == 0) return "#ff7f0e";
    return "#d62728";
  };
  for (size_t ci = 0; ci < cases.size(); ++ci) {
    const int x0 = static_cast<int>(ci % cols) * pw, y0 = static_cast<int>(ci / cols) * ph;
    std::vector<const Row*> pts;
    for (const Row& r : rows) {
      if (r.case_name == cases[ci] && std::isfinite(r.wall_s) && std::isfinite(r.max_rel_error))
        pts.push_back(&r);
    }
    f << "<text x=\"" << x0 + ml << "\" y=\"" << y0 + 18 << "\" font-size=\"13\">" << cases[ci]
      << ": max relative parameter error vs wall time</text>\n";
    if (pts.empty()) continue;
    double tmin = INFINITY, tmax = 0, emin = INFINITY, emax = 0;
    for (const Row* r : pts) {
      tmin = std::min(tmin, r->wall_s);
      tmax = std::max(tmax, r->wall_s);
      const double e = std::max(r->max_rel_error, 1e-12);
      emin = std::min(emin, e);
      emax = std::max(emax, e);
    }
    const double lt0 = std::floor(std::log10(tmin)), lt1 = std::ceil(std::log10(tmax) + 1e-9);
    const double le0 = std::floor(std::log10(emin)), le1 = std::ceil(std::log10(emax) + 1e-9);
    const int w = pw - ml - mr, h = ph - mt - mb;
    auto X = [&](double t) { return x0 + ml + (std::log10(t) - lt0) / (lt1 - lt0) * w; };
    auto Y = [&](double e) {
      return y0 + mt + h - (std::log10(std::max(e, 1e-12)) - le0) / std::max(le1 - le0, 1.0) * h;
    };
    f << "<rect x=\"" << x0 + ml << "\" y=\"" << y0 + mt << "\" width=\"" << w << "\" height=\""
      << h << "\" fill=\"none\" stroke=\"#888\"/>\n";
    for (double d = lt0; d <= lt1; d += 1) {
      f << "<text x=\"" << X(std::pow(10, d)) - 10 << "\" y=\"" << y0 + mt + h + 14 << "\">1e" << d
        << "</text>\n";
    }
    for (double d = le0; d <= std::max(le1, le0 + 1); d += 1) {
      f << "<text x=\"" << x0 + 30 << "\" y=\"" << Y(std::pow(10, d)) + 3 << "\">1e" << d
        << "</text>\n";
    }
    f << "<text x=\"" << x0 + ml + w / 2 - 30 << "\" y=\"" << y0 + ph - 8
      << "\">wall time [s]</text>\n";
    int legend = 0;
    for (const Row* r : pts) {
      const double x = X(r->wall_s), y = Y(r->max_rel_error);
      f << "<circle cx=\"" << x << "\" cy=\"" << y << "\" r=\"4\" fill=\"" << color(r->method)
        << "\" fill-opacity=\"0.7\"/>\n";
      f << "<text x=\"" << x0 + ml + w + 8 << "\" y=\"" << y0 + mt + 10 + 12 * legend++
        << "\" fill=\"" << color(r->method) << "\">" << r->method << " " << r->threads
        << "t: " << Num(r->wall_s, "%.3g") << " s, " << Num(r->max_rel_error, "%.1e")
        << "</text>\n";
    }
  }
  f << "</svg>\n";
  io::WriteFileAtomically(path, f.str());
}

}  // namespace bench
}  // namespace mjsysid

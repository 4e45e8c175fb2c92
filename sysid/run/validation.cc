#include "sysid/run/validation.h"

#include <limits>
#include <stdexcept>

#include "core/simulator.h"
#include "sysid/assess/metrics.h"
#include "sysid/data/sample_grid.h"
#include "sysid/fit/prepare.h"
#include "sysid/solve/residual_model.h"

namespace mjsysid::run {
namespace {

// the value of a fitted variable by name, else fallback
double EstimateOr(const std::vector<ParameterEstimate>& estimates, const std::string& name,
                  bool final_value, double fallback) {
  for (const ParameterEstimate& e : estimates) {
    if (e.name == name) return final_value ? e.value : e.initial;
  }
  return fallback;
}

// the measurement terms of one sensor at the start (final_value false) or at the estimate
MeasurementTerms TermsOf(const std::vector<FitMeasurement>& measurements,
                         const std::vector<ParameterEstimate>& estimates, const std::string& sensor,
                         bool final_value) {
  MeasurementTerms t;
  for (const FitMeasurement& me : measurements) {
    if (me.sensor != sensor) continue;
    t.delay = EstimateOr(estimates, sensor + ".delay", final_value, me.delay.initial);
    t.gain = EstimateOr(estimates, sensor + ".gain", final_value, me.gain.initial);
    t.bias = EstimateOr(estimates, sensor + ".bias", final_value, me.bias.initial);
  }
  return t;
}

}  // namespace

SequenceResult SimulateHeldOut(const mjModel& m, const std::vector<FitParameter>& parameters,
                               const std::vector<FitMeasurement>& measurements,
                               const std::vector<ParameterEstimate>& estimates,
                               const FitSequence& sequence, int threads,
                               std::vector<std::string>* warnings) {
  // the parameters of this model, with their start and estimated values
  std::vector<ParameterSpec> specs;
  std::vector<double> start, estimate;
  for (const FitParameter& p : parameters) {
    if (!p.AppliesTo(sequence.model)) continue;
    specs.push_back(p.target);
    start.push_back(EstimateOr(estimates, p.name, false, p.initial));
    estimate.push_back(EstimateOr(estimates, p.name, true, p.initial));
  }
  SimulatorOptions so;
  so.threads = threads > 0 ? threads : 1;
  Simulator sim(m, specs, so);

  // the result's frame: the fitted sensors' columns, in model order
  SequenceResult sr;
  sr.name = sequence.name;
  sr.model = sequence.model;
  const Eigen::Index T = sequence.measured.rows();
  std::vector<int> cols;  // model sensordata columns kept
  std::vector<std::string> col_sensor;
  for (int id = 0; id < m.nsensor; ++id) {
    const char* raw = mj_id2name(&m, mjOBJ_SENSOR, id);
    const std::string name = raw ? raw : "";
    bool fitted = sequence.sensors.empty();
    for (const std::string& s : sequence.sensors) fitted = fitted || s == name;
    if (!fitted || name.empty()) continue;
    sr.sensor_names.push_back(name);
    sr.sensor_dims.push_back(m.sensor_dim[id]);
    for (int c = 0; c < m.sensor_dim[id]; ++c) {
      cols.push_back(m.sensor_adr[id] + c);
      col_sensor.push_back(name);
    }
  }
  const auto ncol = static_cast<Eigen::Index>(cols.size());
  sr.measured.resize(T, ncol);
  for (Eigen::Index c = 0; c < ncol; ++c) sr.measured.col(c) = sequence.measured.col(cols[c]);
  if (sequence.time.size() == T) {
    sr.time = sequence.time;
  } else {
    sr.time = Eigen::VectorXd::LinSpaced(T, 0, static_cast<double>(T - 1)) * m.opt.timestep;
    sr.time.array() += sequence.x0.time;
  }

  // the log's samples and controls on the simulation grid, as the fit reads them
  // (sysid/data/sample_grid.h: any sample rate, controls held or interpolated, transport delay)
  const double dt = m.opt.timestep;
  const SampleGrid grid =
      BuildSampleGrid(sequence.time, static_cast<int>(T), sequence.x0.time, sequence.ctrl,
                      sequence.ctrl_time, sequence.ctrl_hold, sequence.ctrl_delay, dt,
                      "validation sequence '" + sequence.name + "': ", sequence.ctrl_before);

  // one rollout per point, the measurement terms applied column by column
  for (const bool final_value : {false, true}) {
    RowMatrix& out = final_value ? sr.simulated_final : sr.simulated_initial;
    out = RowMatrix::Constant(T, ncol, std::numeric_limits<double>::quiet_NaN());
    try {
      const std::vector<double>& v = final_value ? estimate : start;
      if (!v.empty()) sim.SetParameters(Eigen::Map<const Eigen::VectorXd>(v.data(), v.size()));
      const Trajectory tr = sim.Rollout(SequenceInput{sequence.x0, grid.ctrl});
      for (Eigen::Index c = 0; c < ncol; ++c) {
        const MeasurementTerms terms = TermsOf(measurements, estimates, col_sensor[c], final_value);
        const Signal simulated{tr.sensors.data() + cols[c], tr.sensors.cols()};
        for (Eigen::Index k = 0; k < T; ++k) {
          out(k, c) =
              terms.Apply(DelayedSample(grid.position[k], tr.T, terms.delay, dt).Value(simulated));
        }
      }
    } catch (const std::exception& e) {
      if (warnings) {
        warnings->push_back("validation sequence '" + sequence.name + "': simulation " +
                            (final_value ? "at the estimate" : "at the start") +
                            " failed: " + e.what());
      }
    }
  }
  sr.channel_fits = ChannelFits(sr);
  return sr;
}

void ApplyFittedControlDelays(const mjModel& m, const std::vector<FitControlDelay>& delays,
                              const std::vector<ParameterEstimate>& estimates,
                              FitSequence* sequence) {
  if (delays.empty()) return;
  const std::vector<int> follows = ControlDelayOfActuators(delays, m);
  sequence->ctrl_delay.resize(static_cast<size_t>(m.nu), 0.0);
  for (size_t i = 0; i < follows.size(); ++i) {
    if (follows[i] < 0) continue;
    const FitControlDelay& cd = delays[static_cast<size_t>(follows[i])];
    sequence->ctrl_delay[i] = EstimateOr(estimates, cd.Name(), true, cd.initial);
  }
}

}  // namespace mjsysid::run

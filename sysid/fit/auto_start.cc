// SolveAutoStarts (sysid/fit/prepare.h): the equation-error starts of `initial: auto` parameters.
#include <string>
#include <vector>

#include "sysid/data/equation_error.h"
#include "sysid/fit/prepare.h"

namespace mjsysid {

std::vector<std::string> SolveAutoStarts(PreparedFit* fit_ptr, int threads) {
  PreparedFit& fit = *fit_ptr;
  std::vector<std::string> notes;
  std::vector<bool> done(fit.params.size(), false);
  for (const FitModel& mo : fit.models) {
    std::vector<FitParameter> params;
    std::vector<int> global, which;
    for (size_t g = 0; g < fit.params.size(); ++g) {
      if (!fit.params[g].AppliesTo(mo.name)) continue;
      if (fit.params[g].initial_auto && !done[g]) which.push_back(static_cast<int>(params.size()));
      global.push_back(static_cast<int>(g));
      params.push_back(fit.params[g]);
    }
    if (which.empty()) continue;
    std::vector<const FitSequence*> sequences;
    for (const FitSequence& s : fit.sequences) {
      if (s.model == mo.name) sequences.push_back(&s);
    }
    const EquationErrorStart start =
        SolveEquationError(*mo.model, params, which, sequences, 5, 4000, threads);
    std::string kept;
    for (int i : which) {
      FitParameter& p = fit.params[global[i]];
      p.initial = start.values[i];
      done[global[i]] = true;
      if (!start.solved[i]) kept += (kept.empty() ? "" : ", ") + p.name;
    }
    notes.push_back("initial: auto (model '" + mo.name + "'): " + start.note +
                    (kept.empty() ? "" : "; at the model's value: " + kept));
  }
  for (FitParameter& p : fit.params) p.initial_auto = false;
  return notes;
}

}  // namespace mjsysid

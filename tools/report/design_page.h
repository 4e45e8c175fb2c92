// The page of `sysid design` (DIR/design.html, beside controls.csv and design.yaml): one
// self-contained file that works offline, like the fit report (tools/report/page.h).
//
// Sections, in order: header (experiment, criterion, horizon, candidates, time, where the
// information was computed); predicted standard errors (per parameter, relative, the experiment's
// current excitation beside the design, with bars on a log scale and the ratio; the worst of each
// marked); controls (per actuator: current and design, the allowed band shaded); predicted motion
// (per hinge and slide joint: current and design, the allowed range band shaded where limited);
// constraints (per excitation: amplitude scale, peaks against the limits, joint range margins,
// the fastest joint, steps with contact, and whether it meets them). The charts are the report's
// interactive charts (tools/report/interactive.h): zoom and hover, one shared time axis.
#pragma once

#include <string>

#include "sysid/design/design.h"

namespace mjsysid::report {

// the page (experiment: the YAML file, shown in the header)
std::string DesignPage(const design::DesignResult& r, const std::string& experiment);

// writes DIR/design.html atomically; returns its path
std::string WriteDesignPage(const design::DesignResult& r, const std::string& experiment,
                            const std::string& dir);

}  // namespace mjsysid::report

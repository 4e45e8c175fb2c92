// The report's three figures, each a size and a drawing (tools/report/canvas.h renders it as PNG
// or inline SVG). What they show is listed in tools/report/report.h.
//
// Sizes in px: cost 900 x 440; parameters 400 x 260 per panel, up to 3 panels per row, under a
// 44 px legend; a sequence 1200 px wide, one 230 px panel per sensor column (two per row when
// there are more than 4 columns) under a 76 px header.
//
// A Figure's drawing refers to the result it was made from: keep that alive while drawing.
#pragma once

#include <string>
#include <vector>

#include "sysid/io/result.h"
#include "tools/report/canvas.h"

namespace mjsysid::report {

struct Figure {
  int width = 0, height = 0;  // px
  Drawing draw;
};

// cost vs iteration, log scale (linear when a cost is <= 0), rejected steps marked
Figure CostFigure(const io::FitResultFile& result);

// one panel per parameter: value over the iterations, final value with its 95% interval, truth
Figure ParametersFigure(const io::FitResultFile& result);

// one panel per sensor column: measured, simulated with the initial and the fitted parameters,
// each panel labelled with its % fit at both (sysid/assess/metrics.h); held_out: a `validation:`
// sequence, its header starting "validation (not fitted)"
Figure SequenceFigure(const SequenceResult& sequence, bool held_out = false);

// a sequence's column labels: its channel names (sysid/assess/metrics.h ChannelNames), "column k"
// for any further column of measured
std::vector<std::string> ColumnLabels(const SequenceResult& sequence);

}  // namespace mjsysid::report

#include "sysid/solve/residual_model.h"

namespace mjsysid {

// each term fitted (its value in m) or fixed at its initial value
MeasurementTerms CurrentTerms(const MeasurementTerms& initial, const TermIndex& index,
                              const double* m) {
  MeasurementTerms t;
  t.delay = index.delay >= 0 && m ? m[index.delay] : initial.delay;
  t.gain = index.gain >= 0 && m ? m[index.gain] : initial.gain;
  t.bias = index.bias >= 0 && m ? m[index.bias] : initial.bias;
  return t;
}

double PriorResidual(double p, double mean, double sigma, double dp_dz, double* derivative) {
  *derivative = dp_dz / sigma;
  return (p - mean) / sigma;
}

}  // namespace mjsysid

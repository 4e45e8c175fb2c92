// Logged states smoothed for differentiation (see state_smoothing.h).
#include "sysid/data/state_smoothing.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace mjsysid {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr int kMinFinite = 5;  // finite samples a window's cubic needs (one more than its degree)
constexpr int kHalfWidths[] = {2, 3, 4, 6, 8, 11, 16, 23, 32, 45, 64};
// the noise and Cp sums read every kCpStride-th sample (unbiased, a quarter of the cost)
constexpr int kCpStride = 4;

// one series: a column of a T x n row-major matrix
struct Series {
  const double* x;
  long stride;
  double at(int k) const { return x[static_cast<ptrdiff_t>(k) * stride]; }
};

// F_h[x] at every sample (fx) and the weight of x_k in its own fit (leverage): the cubic fitted
// with tricube weights (1 - |u|^3)^3, u = (t_j - t_k) / ((h + 1) dt) (dt the mean sample period),
// to the finite samples within +-h (wider where NaN cells leave too few). The weights taper to zero
// at the window's ends, so the filtered sequence is smooth from sample to sample and its
// differences do not amplify the noise of the samples entering and leaving the window (a boxcar
// window's differences would). NaN where the window has fewer than kMinFinite finite samples;
// stride > 1: every stride-th sample only (the others NaN).
void LocalCubic(const std::vector<double>& t, const Series& x, int h, std::vector<double>* fx,
                std::vector<double>* leverage, std::vector<double>* weights2 = nullptr,
                int stride = 1) {
  const int T = static_cast<int>(t.size());
  fx->assign(T, kNaN);
  if (leverage) leverage->assign(T, 0.0);
  if (weights2) weights2->assign(T, 0.0);
  const double period = (t[T - 1] - t[0]) / (T - 1);
  for (int k = 0; k < T; k += stride) {
    // the weighted normal equations of the cubic in u; where NaN cells leave fewer than
    // kMinFinite samples in the window, it widens by up to 4 samples each side
    Eigen::Matrix4d G;
    Eigen::Vector4d b;
    int n = 0, j0 = 0, j1 = 0;
    double tau = 0;
    for (int wide = h; wide <= h + 4 && n < kMinFinite; ++wide) {
      j0 = std::max(0, k - wide), j1 = std::min(T - 1, k + wide);
      tau = (wide + 1) * period;
      G.setZero();
      b.setZero();
      n = 0;
      for (int j = j0; j <= j1; ++j) {
        const double v = x.at(j);
        const double u = (t[j] - t[k]) / tau;
        if (!std::isfinite(v) || !(std::abs(u) < 1)) continue;
        const double a = 1 - std::abs(u * u * u), w = a * a * a;
        const Eigen::Vector4d p(1, u, u * u, u * u * u);
        G.noalias() += w * p * p.transpose();
        b.noalias() += w * v * p;
        ++n;
      }
    }
    if (n < kMinFinite) continue;
    const Eigen::LDLT<Eigen::Matrix4d> ldlt(G);
    (*fx)[k] = ldlt.solve(b)[0];
    if (leverage && std::isfinite(x.at(k))) {
      const Eigen::Vector4d g = ldlt.solve(Eigen::Vector4d::UnitX());
      (*leverage)[k] = g[0];
      // the sum of the squared weights of the window's samples in F[x]_k
      for (int j = j0; weights2 && j <= j1; ++j) {
        const double u = (t[j] - t[k]) / tau;
        if (!std::isfinite(x.at(j)) || !(std::abs(u) < 1)) continue;
        const double a = 1 - std::abs(u * u * u);
        const double w = a * a * a * g.dot(Eigen::Vector4d(1, u, u * u, u * u * u));
        (*weights2)[k] += w * w;
      }
    }
  }
}

// the channel's rounding quantum: the smallest step between consecutive samples when at least
// 90 % of the steps are whole multiples of it (an encoder's counts), else 0
double Quantum(const Series& x, int T) {
  double scale = 0, quantum = std::numeric_limits<double>::infinity();
  for (int k = 0; k < T; ++k) {
    if (std::isfinite(x.at(k))) scale = std::max(scale, std::abs(x.at(k)));
  }
  for (int k = 0; k + 1 < T; ++k) {
    const double step = std::abs(x.at(k + 1) - x.at(k));
    if (step > 1e-12 * scale) quantum = std::min(quantum, step);
  }
  if (!std::isfinite(quantum)) return 0;
  int steps = 0, whole = 0;
  for (int k = 0; k + 1 < T; ++k) {
    const double n = std::abs(x.at(k + 1) - x.at(k)) / quantum;
    if (!(n > 0.5)) continue;  // no step (or a NaN)
    ++steps;
    whole += std::abs(n - std::round(n)) < 0.01;
  }
  return whole >= 0.9 * steps ? quantum : 0;
}

// the channel's noise sigma: from the residuals r of the narrowest fits (h = 3, seven samples at
// their logged times, so uneven stamps do not count as noise), E r_k^2 = sigma^2 (1 - 2 H_kk +
// sum_j w_kj^2) for white noise; and at least the rounding noise quantum / sqrt(12) of a
// quantized channel (a slow quantized signal's residuals are mostly zero)
double NoiseSigma(const std::vector<double>& t, const Series& x) {
  const int T = static_cast<int>(t.size());
  std::vector<double> fx, lev, w2;
  LocalCubic(t, x, 3, &fx, &lev, &w2, kCpStride);
  double rss = 0, dof = 0;
  for (int k = 0; k < T; ++k) {
    const double r = x.at(k) - fx[k];
    if (!std::isfinite(r)) continue;
    rss += r * r;
    dof += 1 - 2 * lev[k] + w2[k];
  }
  const double sigma = dof > 0 ? std::sqrt(rss / dof) : 0.0;
  return std::max(sigma, Quantum(x, T) / std::sqrt(12.0));
}

// the half-width of kHalfWidths that minimises the channels' summed Cp in units of their sigma
int ChooseHalfWidth(const std::vector<double>& t, const std::vector<Series>& channels) {
  const int T = static_cast<int>(t.size());
  std::vector<double> sigma2;
  for (const Series& c : channels) {
    double rms = 0;
    int n = 0;
    for (int k = 0; k < T; ++k) {
      if (std::isfinite(c.at(k))) rms += c.at(k) * c.at(k), ++n;
    }
    rms = n ? std::sqrt(rms / n) : 0;
    // a floor for noise-free channels: their Cp then prefers the least smoothing
    const double s = std::max(NoiseSigma(t, c), 1e-12 * (1 + rms));
    sigma2.push_back(s * s);
  }
  int best = kHalfWidths[0];
  double best_cp = std::numeric_limits<double>::infinity();
  std::vector<double> fx, lev;
  for (int h : kHalfWidths) {
    if (2 * h + 1 > T) break;
    double cp = 0;
    for (size_t c = 0; c < channels.size(); ++c) {
      LocalCubic(t, channels[c], h, &fx, &lev, nullptr, kCpStride);
      for (int k = 0; k < T; ++k) {
        const double r = channels[c].at(k) - fx[k];
        if (std::isfinite(r)) cp += r * r / sigma2[c] + 2 * lev[k];
      }
    }
    if (cp < best_cp) best_cp = cp, best = h;
  }
  return best;
}

// central first and second differences of f at the logged times (NaN at the ends)
double FirstDifference(const std::vector<double>& t, const std::vector<double>& f, int k) {
  if (k <= 0 || k + 1 >= static_cast<int>(t.size())) return kNaN;
  return (f[k + 1] - f[k - 1]) / (t[k + 1] - t[k - 1]);
}
double SecondDifference(const std::vector<double>& t, const std::vector<double>& f, int k) {
  if (k <= 0 || k + 1 >= static_cast<int>(t.size())) return kNaN;
  const double up = (f[k + 1] - f[k]) / (t[k + 1] - t[k]);
  const double down = (f[k] - f[k - 1]) / (t[k] - t[k - 1]);
  return 2 * (up - down) / (t[k + 1] - t[k - 1]);
}

}  // namespace

double LogSampleTime(const mjModel& m, const FitSequence& s, int k) {
  return s.time.size() ? s.time[k] : s.x0.time + k * m.opt.timestep;
}

int HeldControlRow(const FitSequence& s, int k, double t) {
  if (s.ctrl_time.size() == 0) return k;
  const double* b = s.ctrl_time.data();
  const double* it = std::upper_bound(b, b + s.ctrl_time.size(), t);
  return std::max(0, static_cast<int>(it - b) - 1);
}

bool SmoothLoggedStates(const mjModel& m, const FitSequence& s, SmoothedStates* out,
                        std::string* why) {
  const int T = static_cast<int>(s.qpos.rows());
  const bool has_qvel = s.qvel.rows() == T && T > 0;
  if (T == 0) return *why = "the log has no qpos", false;
  if (m.na && s.act.rows() != T) return *why = "the log has no act", false;
  if (T < 16) return *why = "fewer than 16 logged samples", false;
  std::vector<bool> hinge_slide(m.nq, false);  // qpos coordinates that are filtered
  bool all_scalar = true;
  for (int j = 0; j < m.njnt; ++j) {
    const bool scalar = m.jnt_type[j] == mjJNT_HINGE || m.jnt_type[j] == mjJNT_SLIDE;
    if (scalar) hinge_slide[m.jnt_qposadr[j]] = true;
    all_scalar = all_scalar && scalar;
  }
  if (!has_qvel && !all_scalar) {
    return *why = "the log has no qvel and the model has ball or free joints", false;
  }

  std::vector<double> t(T);
  for (int k = 0; k < T; ++k) t[k] = LogSampleTime(m, s, k);

  // the half-width, from the channels that are differentiated
  std::vector<Series> differentiated;
  if (has_qvel) {
    for (int i = 0; i < m.nv; ++i) differentiated.push_back({s.qvel.data() + i, m.nv});
  } else {
    for (int i = 0; i < m.nq; ++i) differentiated.push_back({s.qpos.data() + i, m.nq});
  }
  const int h = ChooseHalfWidth(t, differentiated);

  SmoothedStates& o = *out;
  o.half_width = h;
  o.velocities_from_positions = !has_qvel;
  FitSequence& f = o.states;
  f = FitSequence();
  f.name = s.name;
  f.model = s.model;
  f.x0 = s.x0;
  f.ctrl_before = s.ctrl_before;
  f.time = Eigen::Map<const Eigen::VectorXd>(t.data(), T);
  f.qpos = s.qpos;
  f.qvel.setConstant(T, m.nv, kNaN);
  o.qacc.setConstant(T, m.nv, kNaN);
  std::vector<double> fx;

  // the integrator's velocity convention: semi-implicit Euler (Euler, implicit, implicitfast)
  // carries qvel_k = (qpos_k - qpos_{k-1}) / h, half a timestep h behind the positions, and its
  // one-step acceleration (qvel_{k+1} - qvel_k) / h is centred on t_k; RK4's are aligned
  const double half_step = m.opt.integrator == mjINT_RK4 ? 0.0 : 0.5 * m.opt.timestep;

  // positions (hinge and slide); for encoders the velocities and accelerations from them: central
  // differences of the filtered positions (aligned), the velocity then moved half_step back
  for (int i = 0; i < m.nq; ++i) {
    if (!hinge_slide[i]) continue;
    LocalCubic(t, {s.qpos.data() + i, m.nq}, h, &fx, nullptr);
    for (int k = 0; k < T; ++k) f.qpos(k, i) = fx[k];
  }
  if (!has_qvel) {
    for (int j = 0; j < m.njnt; ++j) {
      const int q = m.jnt_qposadr[j], i = m.jnt_dofadr[j];
      for (int k = 0; k < T; ++k) fx[k] = f.qpos(k, q);
      for (int k = 0; k < T; ++k) {
        o.qacc(k, i) = SecondDifference(t, fx, k);
        f.qvel(k, i) = FirstDifference(t, fx, k) - half_step * o.qacc(k, i);
      }
    }
  }
  // logged velocities and their accelerations. The log's qvel may lag its positions: a
  // simulator's or a drive's backward differences are half a sample behind. The lag delta, one
  // per sequence, is the least-squares fit of F[qvel](t + delta) ~ F[qvel] + delta F[qacc] to the
  // central differences of the filtered hinge and slide positions; qvel is then read at
  // t + delta - half_step (the integrator's convention), the accelerations at t + delta
  if (has_qvel) {
    std::vector<std::vector<double>> fv(m.nv), fa(m.nv, std::vector<double>(T, kNaN));
    for (int i = 0; i < m.nv; ++i) {
      LocalCubic(t, {s.qvel.data() + i, m.nv}, h, &fv[i], nullptr);
      for (int k = 0; k < T; ++k) fa[i][k] = FirstDifference(t, fv[i], k);
    }
    double num = 0, den = 0;
    for (int j = 0; j < m.njnt; ++j) {
      if (!hinge_slide[m.jnt_qposadr[j]]) continue;
      const int i = m.jnt_dofadr[j];
      for (int k = 0; k < T; ++k) fx[k] = f.qpos(k, m.jnt_qposadr[j]);
      for (int k = 0; k < T; ++k) {
        const double r = FirstDifference(t, fx, k) - fv[i][k], a = fa[i][k];
        if (std::isfinite(r) && std::isfinite(a)) num += r * a, den += a * a;
      }
    }
    const double period = (t[T - 1] - t[0]) / (T - 1);
    o.qvel_lag = den > 0 ? std::clamp(num / den, -h * period, h * period) : 0.0;
    for (int i = 0; i < m.nv; ++i) {
      std::vector<double> aligned(T);
      for (int k = 0; k < T; ++k) aligned[k] = fv[i][k] + o.qvel_lag * fa[i][k];
      for (int k = 0; k < T; ++k) {
        o.qacc(k, i) = FirstDifference(t, aligned, k);
        f.qvel(k, i) = aligned[k] - half_step * o.qacc(k, i);
      }
    }
  }
  // activations
  f.act.resize(m.na ? T : 0, m.na);
  for (int i = 0; i < m.na; ++i) {
    LocalCubic(t, {s.act.data() + i, m.na}, h, &fx, nullptr);
    for (int k = 0; k < T; ++k) f.act(k, i) = fx[k];
  }
  // the control each sample applied (clamped as mj_fwdActuation would), then filtered alike
  if (m.nu) {
    RowMatrix applied(T, m.nu);
    const bool clamp = !(m.opt.disableflags & mjDSBL_CLAMPCTRL);
    for (int k = 0; k < T; ++k) {
      applied.row(k) = s.ctrl.row(HeldControlRow(s, k, t[k]));
      for (int a = 0; a < m.nu; ++a) {
        if (clamp && m.actuator_ctrllimited[a]) {
          applied(k, a) = std::clamp(applied(k, a), m.actuator_ctrlrange[2 * a],
                                     m.actuator_ctrlrange[2 * a + 1]);
        }
      }
    }
    f.ctrl.resize(T, m.nu);
    for (int a = 0; a < m.nu; ++a) {
      LocalCubic(t, {applied.data() + a, m.nu}, h, &fx, nullptr);
      for (int k = 0; k < T; ++k) f.ctrl(k, a) = fx[k];
    }
  }
  return true;
}

}  // namespace mjsysid

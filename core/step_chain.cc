// The chain rule over one-step blocks and the tangent/coordinate maps (core/step_chain.h).
#include "core/step_chain.h"

#include <cmath>

namespace mjsysid {
namespace {

using ConstBlock = Eigen::Block<const RowMatrix, Eigen::Dynamic, Eigen::Dynamic, true>;

// block k of a row-major stack of blocks `rows` high
ConstBlock Step(const RowMatrix& M, int k, int rows) {
  return M.middleRows(static_cast<Eigen::Index>(k) * rows, rows);
}

// q (x) (0, w) and Im(q (x) p): the quaternion products of the maps below (w, x, y, z order)
void MulPure(const double q[4], const double w[3], double out[4]) {
  const double p[4] = {0, w[0], w[1], w[2]};
  mju_mulQuat(out, q, p);
}
void ImMulConj(const double q[4], const double p[4], double out[3]) {
  const double qc[4] = {q[0], -q[1], -q[2], -q[3]};
  double r[4];
  mju_mulQuat(r, qc, p);
  out[0] = r[1];
  out[1] = r[2];
  out[2] = r[3];
}

// Calls quat(qadr, dadr) for the qpos address of every ball and free joint quaternion and the
// tangent address of its angular part, and linear(qadr, dadr, n) for each run of n coordinates that
// map one to one (hinges, slides, free positions, velocities, activations).
template <class Quat, class Linear>
void ForEachCoordinate(const mjModel& m, Quat&& quat, Linear&& linear) {
  const int nq = static_cast<int>(m.nq), nv = static_cast<int>(m.nv);
  for (int j = 0; j < m.njnt; ++j) {
    const int qadr = m.jnt_qposadr[j], dadr = m.jnt_dofadr[j];
    switch (m.jnt_type[j]) {
      case mjJNT_FREE:
        linear(qadr, dadr, 3);
        quat(qadr + 3, dadr + 3);
        break;
      case mjJNT_BALL:
        quat(qadr, dadr);
        break;
      default:  // hinge, slide
        linear(qadr, dadr, 1);
    }
  }
  linear(nq, nv, nv);
  linear(nq + nv, 2 * nv, static_cast<int>(m.na));
}

// |q| and q / |q| (the identity for a zero quaternion, as mju_normalize4)
double Normalized(const double* q, double out[4]) {
  const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (n < mjMINVAL) {
    out[0] = 1;
    out[1] = out[2] = out[3] = 0;
    return 1;
  }
  for (int i = 0; i < 4; ++i) out[i] = q[i] / n;
  return n;
}

}  // namespace

void ChainForward(const StepBlocks& b, const Eigen::VectorXd& dx0, const RowMatrix& du,
                  const Eigen::VectorXd& dp, RowMatrix* dx, RowMatrix* dy) {
  const int T = b.T, nx = static_cast<int>(b.A.cols());
  const int ns = T ? static_cast<int>(b.C.rows()) / T : 0;
  const bool with_u = b.B.cols() > 0 && du.size() > 0, with_p = b.F.cols() > 0 && dp.size() > 0;
  dx->resize(T + 1, nx);
  dy->resize(T, ns);
  dx->row(0) = dx0.transpose();
  for (int k = 0; k < T; ++k) {
    // dy_k = C_k dx_k + D_k du_k + G_k dp, dx_{k+1} = A_k dx_k + B_k du_k + F_k dp
    const auto x = dx->row(k).transpose();
    if (ns) {
      auto y = dy->row(k).transpose();
      y.noalias() = Step(b.C, k, ns) * x;
      if (with_u) y.noalias() += Step(b.D, k, ns) * du.row(k).transpose();
      if (with_p) y.noalias() += Step(b.G, k, ns) * dp;
    }
    auto next = dx->row(k + 1).transpose();
    next.noalias() = Step(b.A, k, nx) * x;
    if (with_u) next.noalias() += Step(b.B, k, nx) * du.row(k).transpose();
    if (with_p) next.noalias() += Step(b.F, k, nx) * dp;
  }
}

void ChainBackward(const StepBlocks& b, const RowMatrix& gx, const RowMatrix& gy,
                   Eigen::VectorXd* gx0, RowMatrix* gu, Eigen::VectorXd* gp) {
  const int T = b.T, nx = static_cast<int>(b.A.cols());
  const int ns = T ? static_cast<int>(b.C.rows()) / T : 0;
  const int nu = static_cast<int>(b.B.cols()), np = static_cast<int>(b.F.cols());
  const bool with_x = gx.size() > 0, with_y = gy.size() > 0 && ns > 0;
  gu->setZero(T, nu);
  gp->setZero(np);
  // l = l_{k+1} while step k is visited, from l_T = gx_T
  Eigen::VectorXd l = with_x ? Eigen::VectorXd(gx.row(T).transpose()) : Eigen::VectorXd::Zero(nx);
  Eigen::VectorXd prev(nx);
  for (int k = T - 1; k >= 0; --k) {
    if (nu) gu->row(k).noalias() = (Step(b.B, k, nx).transpose() * l).transpose();
    if (np) gp->noalias() += Step(b.F, k, nx).transpose() * l;
    prev.noalias() = Step(b.A, k, nx).transpose() * l;
    if (with_x) prev += gx.row(k).transpose();
    if (with_y) {
      const auto y = gy.row(k).transpose();
      prev.noalias() += Step(b.C, k, ns).transpose() * y;
      if (nu) gu->row(k).noalias() += (Step(b.D, k, ns).transpose() * y).transpose();
      if (np) gp->noalias() += Step(b.G, k, ns).transpose() * y;
    }
    l.swap(prev);
  }
  *gx0 = l;
}

void ChainJacobians(const StepBlocks& b, RowMatrix* DxDx0, RowMatrix* DyDx0, RowMatrix* DxDp,
                    RowMatrix* DyDp, RowMatrix* DxDu, RowMatrix* DyDu) {
  const int T = b.T, nx = static_cast<int>(b.A.cols());
  const int ns = T ? static_cast<int>(b.C.rows()) / T : 0;
  const int nu = static_cast<int>(b.B.cols()), np = static_cast<int>(b.F.cols());
  // the initial state and the parameters: S_0 = [I | 0], S_{k+1} = A_k S_k + [0 | F_k], sensors
  // C_k S_k + [0 | G_k], both column groups in one pass
  if (DxDx0 || DyDx0 || DxDp || DyDp) {
    RowMatrix S = RowMatrix::Zero(nx, nx + np), next(nx, nx + np), y(ns, nx + np);
    S.leftCols(nx).setIdentity();
    if (DxDx0) DxDx0->resize(static_cast<Eigen::Index>(T + 1) * nx, nx);
    if (DyDx0) DyDx0->resize(static_cast<Eigen::Index>(T) * ns, nx);
    if (DxDp) DxDp->resize(static_cast<Eigen::Index>(T + 1) * nx, np);
    if (DyDp) DyDp->resize(static_cast<Eigen::Index>(T) * ns, np);
    for (int k = 0; k <= T; ++k) {
      if (DxDx0) DxDx0->middleRows(static_cast<Eigen::Index>(k) * nx, nx) = S.leftCols(nx);
      if (DxDp) DxDp->middleRows(static_cast<Eigen::Index>(k) * nx, nx) = S.rightCols(np);
      if (k == T) break;
      if (ns && (DyDx0 || DyDp)) {
        y.noalias() = Step(b.C, k, ns) * S;
        if (np) y.rightCols(np) += Step(b.G, k, ns);
        if (DyDx0) DyDx0->middleRows(static_cast<Eigen::Index>(k) * ns, ns) = y.leftCols(nx);
        if (DyDp) DyDp->middleRows(static_cast<Eigen::Index>(k) * ns, ns) = y.rightCols(np);
      }
      next.noalias() = Step(b.A, k, nx) * S;
      if (np) next.rightCols(np) += Step(b.F, k, nx);
      S.swap(next);
    }
  }
  // the controls of step j: state j+1 gets B_j, later states A_k times it; sensor j gets D_j,
  // later sensors C_k times their state's block
  if (DxDu || DyDu) {
    if (DxDu)
      DxDu->setZero(static_cast<Eigen::Index>(T + 1) * nx, static_cast<Eigen::Index>(T) * nu);
    if (DyDu) DyDu->setZero(static_cast<Eigen::Index>(T) * ns, static_cast<Eigen::Index>(T) * nu);
    if (nu == 0) return;
    RowMatrix S(nx, nu), next(nx, nu);
    for (int j = 0; j < T; ++j) {
      const Eigen::Index col = static_cast<Eigen::Index>(j) * nu;
      if (DyDu && ns)
        DyDu->block(static_cast<Eigen::Index>(j) * ns, col, ns, nu) = Step(b.D, j, ns);
      S = Step(b.B, j, nx);
      for (int k = j + 1; k <= T; ++k) {
        if (DxDu) DxDu->block(static_cast<Eigen::Index>(k) * nx, col, nx, nu) = S;
        if (k == T) break;
        if (DyDu && ns) {
          DyDu->block(static_cast<Eigen::Index>(k) * ns, col, ns, nu).noalias() =
              Step(b.C, k, ns) * S;
        }
        next.noalias() = Step(b.A, k, nx) * S;
        S.swap(next);
      }
    }
  }
}

void NormalizedPhysics(const mjModel& m, const double* x, double* out) {
  const int nphys = static_cast<int>(m.nq + m.nv + m.na);
  for (int i = 0; i < nphys; ++i) out[i] = x[i];
  ForEachCoordinate(
      m, [&](int qadr, int) { Normalized(x + qadr, out + qadr); }, [](int, int, int) {});
}

void TangentToCoordinates(const mjModel& m, const double* x, const double* d, double* dcoords) {
  // a quaternion moves by q (x) (0, w/2); everything else one to one
  ForEachCoordinate(
      m,
      [&](int qadr, int dadr) {
        MulPure(x + qadr, d + dadr, dcoords + qadr);
        for (int i = 0; i < 4; ++i) dcoords[qadr + i] *= 0.5;
      },
      [&](int qadr, int dadr, int n) {
        for (int i = 0; i < n; ++i) dcoords[qadr + i] = d[dadr + i];
      });
}

void CoordinatesToTangentCotangent(const mjModel& m, const double* x, const double* gcoords,
                                   double* g) {
  // the transpose of TangentToCoordinates: w = Im(conj(q) (x) g_q) / 2
  ForEachCoordinate(
      m,
      [&](int qadr, int dadr) {
        ImMulConj(x + qadr, gcoords + qadr, g + dadr);
        for (int i = 0; i < 3; ++i) g[dadr + i] *= 0.5;
      },
      [&](int qadr, int dadr, int n) {
        for (int i = 0; i < n; ++i) g[dadr + i] = gcoords[qadr + i];
      });
}

void CoordinatesToTangent(const mjModel& m, const double* x, const double* dcoords, double* d) {
  // the rollout starts from q / |q|: w = 2 Im(conj(q/|q|) (x) dq) / |q| (the radial part of dq
  // has no imaginary part there)
  ForEachCoordinate(
      m,
      [&](int qadr, int dadr) {
        double q[4];
        const double n = Normalized(x + qadr, q);
        ImMulConj(q, dcoords + qadr, d + dadr);
        for (int i = 0; i < 3; ++i) d[dadr + i] *= 2 / n;
      },
      [&](int qadr, int dadr, int n) {
        for (int i = 0; i < n; ++i) d[dadr + i] = dcoords[qadr + i];
      });
}

void TangentCotangentToCoordinates(const mjModel& m, const double* x, const double* g,
                                   double* gcoords) {
  // the transpose of CoordinatesToTangent: g_q = 2 (q/|q|) (x) (0, g_w) / |q|
  ForEachCoordinate(
      m,
      [&](int qadr, int dadr) {
        double q[4];
        const double n = Normalized(x + qadr, q);
        MulPure(q, g + dadr, gcoords + qadr);
        for (int i = 0; i < 4; ++i) gcoords[qadr + i] *= 2 / n;
      },
      [&](int qadr, int dadr, int n) {
        for (int i = 0; i < n; ++i) gcoords[qadr + i] = g[dadr + i];
      });
}

}  // namespace mjsysid

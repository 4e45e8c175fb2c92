// One-step blocks (Simulator::StepJacobians) and their chain (core/step_chain.h): the blocks chain
// to matrix mode's Jacobians; control, initial-state and parameter derivatives agree with central
// differences of whole rollouts (hinges, a free body's quaternion, activation states); forward and
// backward chains are each other's transpose; the coordinate maps agree with mj_integratePos and
// mj_differentiatePos.
#include "core/step_chain.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace {

const std::string kModels = MJSYSID_MODELS_DIR;
using test::Spec;

// a free body in the air (no contacts: smooth), pushed and twisted by two motors, with position,
// orientation and velocity sensors
constexpr char kFreeBody[] = R"(
<mujoco>
  <option timestep="0.005"/>
  <worldbody>
    <body name="b" pos="0 0 1">
      <freejoint/>
      <geom type="box" size="0.1 0.2 0.05" mass="1.5" contype="0" conaffinity="0"/>
      <site name="s" pos="0.05 0.02 0"/>
    </body>
  </worldbody>
  <actuator>
    <motor site="s" gear="1 0 0.5 0 0 0"/>
    <motor site="s" gear="0 0 0 0.2 0.1 0.3"/>
  </actuator>
  <sensor>
    <framepos objtype="body" objname="b"/>
    <framequat objtype="body" objname="b"/>
    <framelinvel objtype="body" objname="b"/>
  </sensor>
</mujoco>)";

// a hinge driven through a first-order filter actuator (one activation state) and an integrator
constexpr char kActivation[] = R"(
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <body name="link">
      <joint name="j" type="hinge" axis="0 1 0" damping="0.2"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="0.5"/>
    </body>
  </worldbody>
  <actuator>
    <general name="filter" joint="j" dyntype="filter" dynprm="0.03" gainprm="2"/>
    <general name="integrator" joint="j" dyntype="integrator" gainprm="0.5"/>
  </actuator>
  <sensor>
    <jointpos joint="j"/>
    <jointvel joint="j"/>
    <actuatorfrc actuator="filter"/>
  </sensor>
</mujoco>)";

RowMatrix Controls(int T, int nu, double amplitude) {
  RowMatrix u(T, nu);
  for (int k = 0; k < T; ++k) {
    for (int i = 0; i < nu; ++i) u(k, i) = amplitude * std::sin(0.11 * k + 0.9 * i + 0.3);
  }
  return u;
}

// relative max-norm difference, scaled by the larger of the two
double RelDiff(const RowMatrix& a, const RowMatrix& b) {
  const double scale = std::max(a.lpNorm<Eigen::Infinity>(), b.lpNorm<Eigen::Infinity>());
  return (a - b).lpNorm<Eigen::Infinity>() / std::max(scale, 1e-300);
}

// states in tangent space relative to a nominal trajectory, and sensors, stacked as the chain's
// rows: ((T+1) nx + T ns)
Eigen::VectorXd Stack(const mjModel& m, const StateDims& d, const Trajectory& nominal,
                      const Trajectory& tr) {
  Eigen::VectorXd out((tr.T + 1) * d.nx + tr.T * d.ns);
  for (int k = 0; k <= tr.T; ++k) {
    TangentDifference(m, nominal.states.row(k).data(), tr.states.row(k).data(), 1.0,
                      out.data() + k * d.nx);
  }
  for (int k = 0; k < tr.T; ++k) {
    for (int i = 0; i < d.ns; ++i) out[(tr.T + 1) * d.nx + k * d.ns + i] = tr.sensors(k, i);
  }
  return out;
}

// the chain's [DxD*; DyD*] stacked as Stack's rows
RowMatrix Rows(const RowMatrix& Dx, const RowMatrix& Dy) {
  RowMatrix out(Dx.rows() + Dy.rows(), Dx.cols());
  out << Dx, Dy;
  return out;
}

// central differences of whole rollouts along each of `cols` directions: perturb(seq, j, h)
// returns the sequence moved by h along direction j
template <class Perturb>
RowMatrix WholeRolloutDifferences(Simulator& sim, const SequenceInput& seq, int cols, double h,
                                  Perturb&& perturb) {
  const Trajectory nominal = sim.Rollout(seq);
  const StateDims& d = sim.dims();
  RowMatrix out((nominal.T + 1) * d.nx + nominal.T * d.ns, cols);
  for (int j = 0; j < cols; ++j) {
    const Trajectory plus = sim.Rollout(perturb(seq, j, h));
    const Trajectory minus = sim.Rollout(perturb(seq, j, -h));
    out.col(j) =
        (Stack(sim.model(), d, nominal, plus) - Stack(sim.model(), d, nominal, minus)) / (2 * h);
  }
  return out;
}

struct Linearized {
  Trajectory nominal;
  StepBlocks blocks;
};

Linearized Linearize(Simulator& sim, const SequenceInput& seq, bool controls, bool parameters,
                     bool central = true) {
  Linearized out;
  std::vector<Trajectory> nominal;
  std::vector<StepBlocks> blocks;
  sim.Rollout({seq}, &nominal);
  JacobianOptions opt;
  opt.central = central;
  sim.StepJacobians({seq}, nominal, opt, controls, parameters, &blocks);
  out.nominal = nominal[0];
  out.blocks = blocks[0];
  return out;
}

// ---------------------------------------------------------------------------------------------

TEST(StepChainTest, BlocksChainToTheMatrixModeJacobians) {
  // arm7, damping and armature of two joints, 60 steps: the blocks' chain is matrix mode's own
  ModelPtr m = LoadModel(kModels + "/arm7.xml");
  Simulator sim(*m, {Spec("joint_damping", "j2"), Spec("joint_armature", "j4")});
  SequenceInput seq;
  seq.x0 = sim.ReferenceState();
  seq.ctrl = Controls(60, sim.dims().nu, 2.0);
  const Linearized lin = Linearize(sim, seq, false, true, false);
  RowMatrix DxDx0, DyDx0, DxDp, DyDp;
  ChainJacobians(lin.blocks, &DxDx0, &DyDx0, &DxDp, &DyDp, nullptr, nullptr);

  JacobianOptions opt;
  opt.mode = JacobianMode::kMatrix;
  opt.initial_state = true;
  const Sensitivity s = sim.Jacobians(seq, lin.nominal, opt);
  const int np = 2, nx = sim.dims().nx;
  // the same blocks and the same products: equal to rounding
  EXPECT_LT(RelDiff(DxDp, s.DxDp.leftCols(np)), 1e-12);
  EXPECT_LT(RelDiff(DyDp, s.DyDp.leftCols(np)), 1e-12);
  EXPECT_LT(RelDiff(DxDx0, s.DxDp.rightCols(nx)), 1e-12);
  EXPECT_LT(RelDiff(DyDx0, s.DyDp.rightCols(nx)), 1e-12);
}

TEST(StepChainTest, ControlDerivativesMatchWholeRolloutDifferences) {
  // arm7 (7 hinges, 7 motors), 40 steps; truth: central differences of whole rollouts (h 1e-6)
  ModelPtr m = LoadModel(kModels + "/arm7.xml");
  Simulator sim(*m, {});
  SequenceInput seq;
  seq.x0 = sim.ReferenceState();
  seq.ctrl = Controls(40, sim.dims().nu, 2.0);
  const Linearized lin = Linearize(sim, seq, true, false);
  RowMatrix DxDu, DyDu;
  ChainJacobians(lin.blocks, nullptr, nullptr, nullptr, nullptr, &DxDu, &DyDu);
  const int nu = sim.dims().nu;
  // columns of the controls of steps 0, 17 and 39, every actuator
  for (int step : {0, 17, 39}) {
    const RowMatrix fd =
        WholeRolloutDifferences(sim, seq, nu, 1e-6, [&](SequenceInput s, int j, double h) {
          s.ctrl(step, j) += h;
          return s;
        });
    const RowMatrix chain = Rows(DxDu, DyDu).middleCols(step * nu, nu);
    // forward-difference blocks (state step 1e-6, central) against central whole rollouts: both
    // O(h^2) on a smooth arm, differing by the chain's accumulated rounding
    EXPECT_LT(RelDiff(chain, fd), 1e-5) << "controls of step " << step;
  }
}

TEST(StepChainTest, FreeBodyInitialStateDerivativesInTangentSpace) {
  // a free body tumbling for 50 steps from a tilted orientation: the x0 columns (tangent: the
  // quaternion moved on the right, as mj_integratePos) against whole rollouts from x0 moved so
  ModelPtr m = LoadModelFromString(kFreeBody);
  Simulator sim(*m, {});
  SequenceInput seq;
  seq.x0 = sim.ReferenceState();
  const double q[4] = {0.9, 0.3, -0.2, 0.25};
  const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  for (int i = 0; i < 4; ++i) seq.x0.qpos[3 + i] = q[i] / n;
  seq.x0.qvel << 0.3, -0.1, 0.2, 1.5, -0.7, 2.0;
  seq.ctrl = Controls(50, sim.dims().nu, 1.0);
  const Linearized lin = Linearize(sim, seq, true, false);
  RowMatrix DxDx0, DyDx0, DxDu, DyDu;
  ChainJacobians(lin.blocks, &DxDx0, &DyDx0, nullptr, nullptr, &DxDu, &DyDu);
  const int nv = sim.dims().nv;
  const RowMatrix fd =
      WholeRolloutDifferences(sim, seq, sim.dims().nx, 1e-6, [&](SequenceInput s, int j, double h) {
        Eigen::VectorXd dq = Eigen::VectorXd::Zero(nv);
        if (j < nv) {
          dq[j] = 1;
          mj_integratePos(&sim.model(), s.x0.qpos.data(), dq.data(), h);
        } else {
          s.x0.qvel[j - nv] += h;
        }
        return s;
      });
  EXPECT_LT(RelDiff(Rows(DxDx0, DyDx0), fd), 1e-5);
  const RowMatrix fdu =
      WholeRolloutDifferences(sim, seq, sim.dims().nu, 1e-6, [&](SequenceInput s, int j, double h) {
        s.ctrl(0, j) += h;
        return s;
      });
  EXPECT_LT(RelDiff(Rows(DxDu, DyDu).leftCols(sim.dims().nu), fdu), 1e-5);
}

TEST(StepChainTest, ActivationStatesAndParameters) {
  // filter and integrator actuators (na = 2): the act rows and columns of the chain, the control
  // and a parameter (the joint's damping) against whole rollouts, 80 steps
  ModelPtr m = LoadModelFromString(kActivation);
  Simulator sim(*m, {Spec("joint_damping", "j")});
  ASSERT_EQ(sim.dims().na, 2);
  SequenceInput seq;
  seq.x0 = sim.ReferenceState();
  seq.x0.act << 0.1, -0.2;
  seq.ctrl = Controls(80, sim.dims().nu, 1.0);
  const Linearized lin = Linearize(sim, seq, true, true);
  RowMatrix DxDx0, DyDx0, DxDp, DyDp, DxDu, DyDu;
  ChainJacobians(lin.blocks, &DxDx0, &DyDx0, &DxDp, &DyDp, &DxDu, &DyDu);
  const int nx = sim.dims().nx, nq = sim.dims().nq, nv = sim.dims().nv;
  const RowMatrix fdx =
      WholeRolloutDifferences(sim, seq, nx, 1e-6, [&](SequenceInput s, int j, double h) {
        if (j < nv) {
          s.x0.qpos[j] += h;
        } else if (j < 2 * nv) {
          s.x0.qvel[j - nv] += h;
        } else {
          s.x0.act[j - 2 * nv] += h;
        }
        return s;
      });
  EXPECT_EQ(nq, nv);
  EXPECT_LT(RelDiff(Rows(DxDx0, DyDx0), fdx), 1e-5);
  const RowMatrix fdu =
      WholeRolloutDifferences(sim, seq, sim.dims().nu, 1e-6, [&](SequenceInput s, int j, double h) {
        s.ctrl(10, j) += h;
        return s;
      });
  EXPECT_LT(RelDiff(Rows(DxDu, DyDu).middleCols(10 * sim.dims().nu, sim.dims().nu), fdu), 1e-5);
  // the parameter: whole rollouts at damping +- h
  const double p = sim.GetParameters()[0], h = 1e-6;
  Eigen::VectorXd v(1);
  v[0] = p + h;
  sim.SetParameters(v);
  const Trajectory plus = sim.Rollout(seq);
  v[0] = p - h;
  sim.SetParameters(v);
  const Trajectory minus = sim.Rollout(seq);
  v[0] = p;
  sim.SetParameters(v);
  const Eigen::VectorXd fdp =
      (Stack(*m, sim.dims(), lin.nominal, plus) - Stack(*m, sim.dims(), lin.nominal, minus)) /
      (2 * h);
  EXPECT_LT(RelDiff(Rows(DxDp, DyDp), RowMatrix(fdp)), 1e-5);
}

TEST(StepChainTest, ForwardAndBackwardChainsAreTransposes) {
  // <gx, dx> + <gy, dy> = <gx0, dx0> + <gu, du> + <gp, dp> for random directions and cotangents
  ModelPtr m = LoadModel(kModels + "/arm7.xml");
  Simulator sim(*m, {Spec("joint_damping", "j1"), Spec("joint_armature", "j3")});
  SequenceInput seq;
  seq.x0 = sim.ReferenceState();
  seq.ctrl = Controls(30, sim.dims().nu, 2.0);
  const Linearized lin = Linearize(sim, seq, true, true, false);
  const int T = 30, nx = sim.dims().nx, ns = sim.dims().ns, nu = sim.dims().nu;
  std::mt19937 rng(7);
  std::normal_distribution<double> g;
  auto random = [&](int r, int c) {
    RowMatrix M(r, c);
    for (int i = 0; i < M.size(); ++i) M.data()[i] = g(rng);
    return M;
  };
  const Eigen::VectorXd dx0 = random(nx, 1), dp = random(2, 1);
  const RowMatrix du = random(T, nu), gx = random(T + 1, nx), gy = random(T, ns);
  RowMatrix dx, dy, gu;
  Eigen::VectorXd gx0, gp;
  ChainForward(lin.blocks, dx0, du, dp, &dx, &dy);
  ChainBackward(lin.blocks, gx, gy, &gx0, &gu, &gp);
  const double lhs = (gx.array() * dx.array()).sum() + (gy.array() * dy.array()).sum();
  const double rhs = gx0.dot(dx0) + (gu.array() * du.array()).sum() + gp.dot(dp);
  EXPECT_NEAR(lhs, rhs, 1e-10 * std::abs(lhs));
}

TEST(StepChainTest, CoordinateMapsAgreeWithMujocoOnQuaternions) {
  // at a free body's state with a non-unit quaternion (|q| = 1.3): the maps against
  // mj_integratePos / mj_differentiatePos of the normalised state, and each map against its
  // transpose
  ModelPtr m = LoadModelFromString(kFreeBody);
  const StateDims d(*m);
  std::mt19937 rng(3);
  std::normal_distribution<double> g;
  Eigen::VectorXd x(d.nphys), xn(d.nphys);
  for (int i = 0; i < d.nphys; ++i) x[i] = g(rng);
  const double q[4] = {0.7, 0.5, -0.6, 0.4};  // |q| = 1.1489...
  for (int i = 0; i < 4; ++i) x[3 + i] = 1.3 * q[i] / std::sqrt(0.7 * 0.7 + 0.25 + 0.36 + 0.16);
  NormalizedPhysics(*m, x.data(), xn.data());
  EXPECT_NEAR(xn.segment(3, 4).norm(), 1.0, 1e-15);

  const double h = 1e-7;
  Eigen::VectorXd dc(d.nphys), dt(d.nx), expect(d.nx), xp(d.nphys), xpn(d.nphys);
  for (int i = 0; i < d.nphys; ++i) dc[i] = g(rng);
  // CoordinatesToTangent: d(normalise(x + h dc) (-) normalise(x)) / h
  CoordinatesToTangent(*m, x.data(), dc.data(), dt.data());
  xp = x + h * dc;
  NormalizedPhysics(*m, xp.data(), xpn.data());
  TangentDifference(*m, xn.data(), xpn.data(), 1.0 / h, expect.data());
  EXPECT_LT((dt - expect).lpNorm<Eigen::Infinity>(), 1e-6 * expect.lpNorm<Eigen::Infinity>());
  // TangentToCoordinates: (xn (+) h dt - xn) / h
  Eigen::VectorXd back(d.nphys);
  TangentToCoordinates(*m, xn.data(), dt.data(), back.data());
  DataPtr data = MakeData(*m);
  SetPhysics(*m, data.get(), xn.data());
  TangentPerturb(*m, data.get(), dt.data(), h);
  GetPhysics(*m, *data, xp.data());
  const Eigen::VectorXd fd = (xp - xn) / h;
  EXPECT_LT((back - fd).lpNorm<Eigen::Infinity>(), 1e-6 * fd.lpNorm<Eigen::Infinity>());
  // the transposes: <g, M v> = <M^T g, v>
  Eigen::VectorXd gc(d.nphys), gt(d.nx), v(d.nx), Mv(d.nphys), Mtg(d.nx), Mc(d.nx), Mtc(d.nphys);
  for (int i = 0; i < d.nphys; ++i) gc[i] = g(rng);
  for (int i = 0; i < d.nx; ++i) v[i] = g(rng), gt[i] = g(rng);
  TangentToCoordinates(*m, xn.data(), v.data(), Mv.data());
  CoordinatesToTangentCotangent(*m, xn.data(), gc.data(), Mtg.data());
  EXPECT_NEAR(gc.dot(Mv), Mtg.dot(v), 1e-12);
  CoordinatesToTangent(*m, x.data(), dc.data(), Mc.data());
  TangentCotangentToCoordinates(*m, x.data(), gt.data(), Mtc.data());
  EXPECT_NEAR(gt.dot(Mc), Mtc.dot(dc), 1e-12);
}

TEST(StepChainTest, RefusesModelsWithoutOneStepDerivatives) {
  // RK4: mjd_transitionFD does not support it; a bad nominal: the sequence's rows
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  m->opt.integrator = mjINT_RK4;
  Simulator sim(*m, {});
  SequenceInput seq;
  seq.x0 = sim.ReferenceState();
  seq.ctrl = Controls(5, sim.dims().nu, 1.0);
  std::vector<Trajectory> nominal;
  std::vector<StepBlocks> blocks;
  sim.Rollout({seq}, &nominal);
  EXPECT_THROW(sim.StepJacobians({seq}, nominal, JacobianOptions(), true, true, &blocks),
               std::invalid_argument);
  ModelPtr ok = LoadModel(kModels + "/pendulum.xml");
  Simulator sim2(*ok, {});
  nominal.clear();
  sim2.Rollout({seq}, &nominal);
  SequenceInput longer = seq;
  longer.ctrl = Controls(6, sim2.dims().nu, 1.0);
  EXPECT_THROW(sim2.StepJacobians({longer}, nominal, JacobianOptions(), true, true, &blocks),
               std::invalid_argument);
}

}  // namespace
}  // namespace mjsysid

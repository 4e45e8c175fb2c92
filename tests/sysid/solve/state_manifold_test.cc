#include "sysid/solve/state_manifold.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "core/mujoco_env.h"

namespace mjsysid {
namespace {

const std::string kModels = MJSYSID_MODELS_DIR;

// a rotated, moving state of the free box (nq 7, nv 6)
std::vector<double> BoxState(const mjModel& m) {
  std::vector<double> x(m.nq + m.nv + m.na, 0.0);
  x[0] = 0.3, x[1] = -0.2, x[2] = 0.5;
  const double a = 0.7;
  x[3] = std::cos(a), x[4] = std::sin(a) * 0.48, x[5] = std::sin(a) * 0.6,
  x[6] = std::sin(a) * 0.64;
  for (int i = 0; i < m.nv; ++i) x[m.nq + i] = 0.1 * (i + 1);
  return x;
}

TEST(StateManifoldTest, SizesPlusMinusRoundTrip) {
  ModelPtr m = LoadModel(kModels + "/box_floor.xml");
  StateManifold M(m.get());
  EXPECT_EQ(M.AmbientSize(), 13);
  EXPECT_EQ(M.TangentSize(), 12);
  const std::vector<double> x = BoxState(*m);
  std::vector<double> delta(12), y(13), back(12);
  for (int i = 0; i < 12; ++i) delta[i] = 0.05 * std::sin(1.0 + 2 * i);
  ASSERT_TRUE(M.Plus(x.data(), delta.data(), y.data()));
  double norm = 0;
  for (int i = 3; i < 7; ++i) norm += y[i] * y[i];
  EXPECT_NEAR(norm, 1.0, 1e-14) << "quaternion stays unit";
  ASSERT_TRUE(M.Minus(y.data(), x.data(), back.data()));
  for (int i = 0; i < 12; ++i) EXPECT_NEAR(back[i], delta[i], 1e-12) << i;
}

// PlusJacobian against central differences of Plus; the pseudo-inverse inverts it
TEST(StateManifoldTest, PlusJacobianMatchesFiniteDifferences) {
  for (const char* name : {"box_floor.xml", "ball_pendulum.xml", "arm5.xml"}) {
    SCOPED_TRACE(name);
    ModelPtr m = LoadModel(kModels + "/" + name);
    StateManifold M(m.get());
    const int na = M.AmbientSize(), nt = M.TangentSize();
    std::vector<double> x(na, 0.0);
    if (std::string(name) == "box_floor.xml") {
      x = BoxState(*m);
    } else {
      for (int i = 0; i < m->nq; ++i) x[i] = m->qpos0[i];
      if (std::string(name) == "ball_pendulum.xml") {
        x[0] = std::cos(0.3), x[1] = std::sin(0.3) * 0.6, x[2] = std::sin(0.3) * 0.8, x[3] = 0;
      }
    }
    std::vector<double> P(static_cast<size_t>(na) * nt), pinv(static_cast<size_t>(nt) * na);
    ASSERT_TRUE(M.PlusJacobian(x.data(), P.data()));
    M.PlusJacobianPseudoInverse(x.data(), pinv.data());
    const double h = 1e-6;
    for (int c = 0; c < nt; ++c) {
      std::vector<double> d(nt, 0.0), yp(na), ym(na);
      d[c] = h;
      M.Plus(x.data(), d.data(), yp.data());
      d[c] = -h;
      M.Plus(x.data(), d.data(), ym.data());
      for (int r = 0; r < na; ++r) {
        EXPECT_NEAR(P[r * nt + c], (yp[r] - ym[r]) / (2 * h), 1e-8) << "row " << r << " col " << c;
      }
    }
    // P^+ P = I
    for (int i = 0; i < nt; ++i) {
      for (int j = 0; j < nt; ++j) {
        double v = 0;
        for (int r = 0; r < na; ++r) v += pinv[i * na + r] * P[r * nt + j];
        EXPECT_NEAR(v, i == j ? 1.0 : 0.0, 1e-12);
      }
    }
  }
}

}  // namespace
}  // namespace mjsysid

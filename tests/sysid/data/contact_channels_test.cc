// DiscontinuousChannelWarnings (sysid/data/contact_channels.h) on real MuJoCo rollouts: a box
// dropped on the floor (contacts switch on at the impact) with a touch sensor under it, an
// accelerometer, a force sensor and a frame position; the same box high above the floor (no contact
// at all).
#include "sysid/data/contact_channels.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/simulator.h"

namespace mjsysid {
namespace {

// a 1 kg box on a slide joint (z) released at height HEIGHT above a floor
std::string Box(double height) {
  return R"(<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="box" pos="0 0 )" +
         std::to_string(height) + R"(">
      <joint name="z" type="slide" axis="0 0 1"/>
      <geom name="box" type="box" size="0.1 0.1 0.1" mass="1"/>
      <site name="bottom" type="box" pos="0 0 -0.1" size="0.11 0.11 0.02"/>
      <site name="imu"/>
    </body>
  </worldbody>
  <sensor>
    <touch name="touch" site="bottom"/>
    <accelerometer name="accel" site="imu"/>
    <force name="force" site="imu"/>
    <framepos name="pos" objtype="site" objname="imu"/>
    <jointpos name="z" joint="z"/>
  </sensor>
</mujoco>)";
}

std::vector<Trajectory> Drop(const mjModel& m, int steps) {
  Simulator sim(m, {});
  SequenceInput in;
  in.x0.qpos = Eigen::VectorXd::Zero(m.nq);
  in.x0.qvel = Eigen::VectorXd::Zero(m.nv);
  in.ctrl = RowMatrix::Zero(steps, m.nu);
  return {sim.Rollout(in)};
}

// released 5 cm above the floor: it lands within 0.2 s (500 steps = 1 s), so the contact count
// changes; touch, accelerometer and force are named, the frame position and joint encoder not
TEST(ContactChannelsTest, NamesTouchAccelerometerAndForceWhenContactsSwitch) {
  ModelPtr m = LoadModelFromString(Box(0.15));
  const std::vector<Trajectory> tr = Drop(*m, 500);
  const std::vector<std::string> w =
      DiscontinuousChannelWarnings(*m, {"touch", "accel", "force", "pos", "z"}, tr);
  ASSERT_EQ(w.size(), 3u);
  EXPECT_NE(w[0].find("sensor 'touch' (touch) jumps"), std::string::npos) << w[0];
  EXPECT_NE(w[1].find("sensor 'accel' (accelerometer)"), std::string::npos) << w[1];
  EXPECT_NE(w[2].find("sensor 'force' (force)"), std::string::npos) << w[2];
  EXPECT_NE(w[0].find(" in 500 steps"), std::string::npos) << w[0];
  // only the fitted sensors are looked at
  EXPECT_TRUE(DiscontinuousChannelWarnings(*m, {"pos", "z"}, tr).empty());
}

// released 1 m above the floor for 0.2 s: it falls 0.2 m and never touches, so nothing jumps
TEST(ContactChannelsTest, SilentWithoutContactEvents) {
  ModelPtr m = LoadModelFromString(Box(1.0));
  const std::vector<Trajectory> tr = Drop(*m, 100);
  EXPECT_TRUE(DiscontinuousChannelWarnings(*m, {"touch", "accel", "force"}, tr).empty());
}

}  // namespace
}  // namespace mjsysid

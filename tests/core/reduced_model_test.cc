// The reduced model (core/reduced_model.h): what the analysis switches off on shipped and small
// inline models, and that a reduced Simulator's rollouts and Jacobians equal the full model's bit
// for bit, also when the guard trips and the call is simulated again with the full model.
// Exact equality (not a tolerance) is the claim: a switched-off feature must change no number.
#include "core/reduced_model.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace {

const std::string kModels = MJSYSID_MODELS_DIR;

// a hinged arm (rod and ball, one weld body) swinging next to a post, over a floor; both world
// geoms are filtered against each other, the rod and ball against each other (one weld body), so
// the candidates are {floor, post} x {rod, ball}. At rest the ball's sphere is 0.35 m from the
// post's, the rod's 0.08 m; the post sits on the ball's circle (at 53 degrees), so a strong
// negative torque swings the ball into it.
constexpr char kSwingXml[] = R"(
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <geom name="post" type="sphere" size="0.05" pos="0.4 0 0.7"/>
    <body name="arm" pos="0 0 1">
      <joint name="hinge" type="hinge" axis="0 1 0" damping="0.1"/>
      <geom name="rod" type="capsule" fromto="0 0 0 0 0 -0.5" size="0.02"/>
      <body name="ball" pos="0 0 -0.5">
        <geom name="ball" type="sphere" size="0.05" mass="1"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor name="torque" joint="hinge" ctrlrange="-20 20"/></actuator>
  <sensor><jointpos name="angle" joint="hinge"/><jointvel name="rate" joint="hinge"/></sensor>
</mujoco>)";

// a free box resting on a floor, and a lamp (a world sphere) 3 m above it: the box-floor pair is
// always in contact, the box-lamp pair never near
constexpr char kBoxLampXml[] = R"(
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1" friction="0.5"/>
    <geom name="lamp" type="sphere" size="0.1" pos="0 0 3"/>
    <body name="box" pos="0 0 0.1">
      <freejoint name="slide"/>
      <geom name="box" type="box" size="0.1 0.1 0.1" mass="1"/>
    </body>
  </worldbody>
  <actuator><motor name="push" joint="slide" gear="1 0 0 0 0 0" ctrlrange="-20 20"/></actuator>
  <sensor><framepos name="pos" objtype="body" objname="box"/></sensor>
</mujoco>)";

// nominal rollouts of m from its reference state with controls ctrl, by a full simulator
std::vector<Trajectory> Nominal(const mjModel& m, const std::vector<RowMatrix>& ctrls) {
  Simulator sim(m, {});
  std::vector<SequenceInput> ins;
  for (const RowMatrix& u : ctrls) ins.push_back({sim.ReferenceState(), u});
  std::vector<Trajectory> trs;
  sim.Rollout(ins, &trs);
  return trs;
}

ModelReduction Analyze(const mjModel& m, const std::vector<Trajectory>& trs) {
  std::vector<const RowMatrix*> states;
  std::vector<const Eigen::VectorXd*> inputs;
  for (const Trajectory& tr : trs) {
    states.push_back(&tr.states);
    inputs.push_back(&tr.inputs);
  }
  return AnalyzeReduction(m, StateDims(m), states, inputs);
}

// rollouts and Jacobians (mode) of a full and a reduced simulator of m with parameters specs,
// compared bit for bit, on controls ctrl, with `threads` workers (2: the directional columns run
// behind the rollout, RolloutAndJacobians); returns the reduced simulator's guard trips
int ExpectSameAsFull(const mjModel& m, const std::vector<ParameterSpec>& specs,
                     const ModelReduction& r, const RowMatrix& ctrl, JacobianMode mode,
                     int threads = 1) {
  SimulatorOptions so;
  so.threads = threads;
  Simulator full(m, specs, so), reduced(m, specs, so);
  reduced.SetReduction(r);
  EXPECT_EQ(reduced.ContactsPossible(), full.ContactsPossible());
  const SequenceInput in{full.ReferenceState(), ctrl};
  JacobianOptions jo;
  jo.mode = mode;
  jo.initial_state = true;
  test::ExpectSameSimulation(full, reduced, in, jo);
  return reduced.ReductionTrips();
}

// the pendulum has two geoms in one weld body: no pair can collide, collision goes off as a whole,
// and one kinematic tree makes island discovery inert; states, sensors and Jacobians unchanged
TEST(ReducedModelTest, PendulumSwitchesOffCollisionAndIslands) {
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  const RowMatrix u = test::Excitation(*m, 800, 2.0, 1);
  const ModelReduction r = Analyze(*m, Nominal(*m, {u}));
  EXPECT_EQ(r.disable, mjDSBL_CONTACT | mjDSBL_ISLAND);
  EXPECT_EQ(r.candidate_pairs, 0);
  EXPECT_EQ(r.Summary(), "collision_pairs_off: 0 of 0, geoms_off: 0, disabled: [contact, island]");
  const std::vector<ParameterSpec> specs = {test::Spec("joint_damping", "hinge"),
                                            test::Spec("body_mass", "bob")};
  for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kMatrix}) {
    EXPECT_EQ(ExpectSameAsFull(*m, specs, r, u, mode), 0);
  }
}

// the cart-pole's cart and pole are parent and child (filtered): collision off, and the rollout
// equal to the full model's shows that MuJoCo filters that pair too
TEST(ReducedModelTest, CartpoleParentChildPairIsFiltered) {
  ModelPtr m = LoadModel(kModels + "/cartpole.xml");
  const RowMatrix u = test::Excitation(*m, 800, 10.0, 2);
  const ModelReduction r = Analyze(*m, Nominal(*m, {u}));
  EXPECT_EQ(r.disable, mjDSBL_CONTACT | mjDSBL_ISLAND);
  EXPECT_EQ(r.candidate_pairs, 0);
  EXPECT_EQ(ExpectSameAsFull(*m, {test::Spec("joint_damping", "slider")}, r, u,
                             JacobianMode::kDirectional),
            0);
}

// box on a floor under a lamp: the lamp goes off (its one pair stays 2.7 m away), the floor stays
// (the box rests on it); contacts, solver and Jacobians unchanged
TEST(ReducedModelTest, BoxOnFloorSwitchesOffTheFarGeomOnly) {
  ModelPtr m = LoadModelFromString(kBoxLampXml);
  const RowMatrix u = test::Excitation(*m, 600, 8.0, 3);
  const ModelReduction r = Analyze(*m, Nominal(*m, {u}));
  EXPECT_EQ(r.candidate_pairs, 2);
  EXPECT_EQ(r.pairs_off, 1);
  ASSERT_EQ(r.geoms_off.size(), 1u);
  EXPECT_EQ(r.geoms_off[0], mj_name2id(m.get(), mjOBJ_GEOM, "lamp"));
  EXPECT_EQ(r.disable, mjDSBL_ISLAND);
  const std::vector<ParameterSpec> specs = {test::Spec("geom_friction", "box"),
                                            test::Spec("body_mass", "box")};
  for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kMatrix}) {
    EXPECT_EQ(ExpectSameAsFull(*m, specs, r, u, mode), 0);
  }
  // the lamp's switches are restored when the reduction is dropped by a new SetReduction
  Simulator sim(*m, {});
  sim.SetReduction(r);
  EXPECT_EQ(sim.model().geom_contype[r.geoms_off[0]], 0);
  sim.SetReduction(ModelReduction());
  EXPECT_EQ(sim.model().geom_contype[r.geoms_off[0]], m->geom_contype[r.geoms_off[0]]);
  EXPECT_EQ(sim.model().opt.disableflags, m->opt.disableflags);
}

// the shipped box_floor (box sliding on the floor, pushed by up to 25 N): islands off (one tree),
// the box-floor pair on; rollouts and Jacobians the same at the experiment's start values
TEST(ReducedModelTest, BoxFloorKeepsItsContactAndSwitchesOffIslands) {
  ModelPtr m = LoadModel(kModels + "/box_floor.xml");
  const RowMatrix u = test::Excitation(*m, 600, 25.0, 3);
  const ModelReduction r = Analyze(*m, Nominal(*m, {u}));
  EXPECT_EQ(r.disable, mjDSBL_ISLAND);
  EXPECT_EQ(r.candidate_pairs, 1);
  EXPECT_EQ(r.pairs_off, 0);
  const std::vector<ParameterSpec> specs = {test::Spec("geom_friction", "box"),
                                            test::Spec("body_mass", "box")};
  for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kMatrix}) {
    EXPECT_EQ(ExpectSameAsFull(*m, specs, r, u, mode), 0);
  }
}

// the arm analysed on small swings (0.5 N m: all four pairs far, collision off as a whole), then
// driven by -20 N m into the post: the guard trips, and the call is simulated again with the full
// model: the same numbers as the full model (which has contacts there: without the guard the
// numbers would differ, shown), one trip, the reduction dropped
TEST(ReducedModelTest, GuardTripsWhenAnArmSwingsIntoThePost) {
  ModelPtr m = LoadModelFromString(kSwingXml);
  const RowMatrix small = test::Excitation(*m, 500, 0.5, 4);
  const ModelReduction r = Analyze(*m, Nominal(*m, {small}));
  EXPECT_EQ(r.candidate_pairs, 4);
  EXPECT_EQ(r.pairs_off, 4);
  EXPECT_EQ(r.disable, mjDSBL_CONTACT | mjDSBL_ISLAND);
  const std::vector<ParameterSpec> specs = {test::Spec("joint_damping", "hinge")};
  EXPECT_EQ(ExpectSameAsFull(*m, specs, r, small, JacobianMode::kDirectional), 0);

  const RowMatrix turn = RowMatrix::Constant(1500, 1, -20.0);
  // what collision off would give unguarded: other states (the ball passes through the post)
  ModelPtr off = CopyModel(*m);
  off->opt.disableflags |= mjDSBL_CONTACT;
  Simulator unguarded(*off, specs), full(*m, specs);
  const Trajectory t_off = unguarded.Rollout({unguarded.ReferenceState(), turn});
  const Trajectory t_full = full.Rollout({full.ReferenceState(), turn});
  EXPECT_GT(*std::max_element(t_full.ncon.begin(), t_full.ncon.end()), 0);
  EXPECT_GT((t_off.states - t_full.states).cwiseAbs().maxCoeff(), 0.1);
  EXPECT_EQ(ExpectSameAsFull(*m, specs, r, turn, JacobianMode::kDirectional), 1);
  EXPECT_EQ(ExpectSameAsFull(*m, specs, r, turn, JacobianMode::kDirectional, 2), 1);
  EXPECT_EQ(ExpectSameAsFull(*m, specs, r, turn, JacobianMode::kMatrix, 2), 1);
  Simulator sim(*m, specs);
  sim.SetReduction(r);
  EXPECT_TRUE(sim.reduced());
  sim.Rollout({sim.ReferenceState(), turn});
  EXPECT_FALSE(sim.reduced());
  EXPECT_EQ(sim.ReductionTrips(), 1);
  EXPECT_EQ(sim.model().opt.disableflags, m->opt.disableflags);
}

// the guard's test itself: clear at rest, not clear with the ball moved next to the post
TEST(ReducedModelTest, GuardMeasuresBoundingSphereGaps) {
  ModelPtr m = LoadModelFromString(kSwingXml);
  const RowMatrix small = test::Excitation(*m, 200, 0.5, 5);
  const ModelReduction r = Analyze(*m, Nominal(*m, {small}));
  DataPtr d = MakeData(*m);
  mj_kinematics(m.get(), d.get());
  EXPECT_TRUE(ReductionGuardClear(r, *m, *d));
  d->qpos[0] = -0.85;  // the ball at x = 0.38, z = 0.67: 0.04 m from the post's centre
  mj_kinematics(m.get(), d.get());
  EXPECT_FALSE(ReductionGuardClear(r, *m, *d));
}

}  // namespace
}  // namespace mjsysid

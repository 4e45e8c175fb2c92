#include "core/reduced_model.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/mujoco_env.h"

namespace mjsysid {
namespace {

// analysing more pair-samples than this is not worth its time: collision stays as it is
constexpr double kMaxPairSamples = 2e8;

// MuJoCo's contact margin of a geom pair (mj_assignMargin): the larger geom margin, or the
// override margin
double PairMargin(const mjModel& m, int g1, int g2) {
  if (m.opt.enableflags & mjENBL_OVERRIDE) return m.opt.o_margin;
  return std::max(m.geom_margin[g1], m.geom_margin[g2]);
}

// bounding-sphere gap of geoms g1, g2 at the poses in d: centre distance minus both radii; for a
// plane (rbound 0) the other sphere's height above it minus its radius; -inf when it cannot be
// bounded (two planes, another unbounded geom)
double SphereGap(const mjModel& m, const mjData& d, int g1, int g2) {
  const double r1 = m.geom_rbound[g1], r2 = m.geom_rbound[g2];
  if (r1 > 0 && r2 > 0) {
    return mju_dist3(d.geom_xpos + 3 * g1, d.geom_xpos + 3 * g2) - r1 - r2;
  }
  if (r1 > 0 || r2 > 0) {
    const int plane = r1 > 0 ? g2 : g1, other = r1 > 0 ? g1 : g2;
    if (m.geom_type[plane] != mjGEOM_PLANE) return -std::numeric_limits<double>::infinity();
    const double* mat = d.geom_xmat + 9 * plane;  // row-major: the normal is the third column
    const double normal[3] = {mat[2], mat[5], mat[8]};
    double rel[3];
    mju_sub3(rel, d.geom_xpos + 3 * other, d.geom_xpos + 3 * plane);
    return mju_dot3(normal, rel) - m.geom_rbound[other];
  }
  return -std::numeric_limits<double>::infinity();
}

// whether MuJoCo's broad phase may pair geoms g1 and g2 (contype/conaffinity, same weld body,
// parent and child); explicit <exclude> elements are ignored (the pair stays a candidate)
bool CanCollide(const mjModel& m, int g1, int g2) {
  const bool compatible = (m.geom_contype[g1] & m.geom_conaffinity[g2]) ||
                          (m.geom_contype[g2] & m.geom_conaffinity[g1]);
  if (!compatible) return false;
  const int weld1 = m.body_weldid[m.geom_bodyid[g1]], weld2 = m.body_weldid[m.geom_bodyid[g2]];
  if (weld1 == weld2) return false;
  if (!(m.opt.disableflags & mjDSBL_FILTERPARENT) && weld1 != 0 && weld2 != 0) {
    const int parent1 = m.body_weldid[m.body_parentid[weld1]];
    const int parent2 = m.body_weldid[m.body_parentid[weld2]];
    if (weld1 == parent2 || weld2 == parent1) return false;
  }
  return true;
}

}  // namespace

std::vector<std::string> DisabledNames(int disable) {
  std::vector<std::string> names;
  if (disable & mjDSBL_CONTACT) names.push_back("contact");
  if (disable & mjDSBL_ISLAND) names.push_back("island");
  return names;
}

std::string ModelReduction::Summary() const {
  std::string s = "collision_pairs_off: " + std::to_string(pairs_off) + " of " +
                  std::to_string(candidate_pairs) +
                  ", geoms_off: " + std::to_string(geoms_off.size()) + ", disabled: [";
  const std::vector<std::string> names = DisabledNames(disable);
  for (size_t i = 0; i < names.size(); ++i) s += (i ? ", " : "") + names[i];
  return s + "]";
}

ModelReduction AnalyzeReduction(const mjModel& m, const StateDims& dims,
                                const std::vector<const RowMatrix*>& states,
                                const std::vector<const Eigen::VectorXd*>& inputs) {
  ModelReduction r;

  // island discovery: inert with at most one kinematic tree (one island at most) and no sleeping
  if (m.ntree <= 1 && !(m.opt.enableflags & mjENBL_SLEEP) &&
      !(m.opt.disableflags & mjDSBL_ISLAND)) {
    r.disable |= mjDSBL_ISLAND;
  }
  if (m.opt.disableflags & (mjDSBL_CONTACT | mjDSBL_CONSTRAINT)) return r;

  // collision candidates: geom pairs the broad phase may pair
  std::vector<std::pair<int, int>> pairs;
  for (int g1 = 0; g1 < m.ngeom; ++g1) {
    if (!m.geom_contype[g1] && !m.geom_conaffinity[g1]) continue;
    for (int g2 = g1 + 1; g2 < m.ngeom; ++g2) {
      if (CanCollide(m, g1, g2)) pairs.emplace_back(g1, g2);
    }
  }
  r.candidate_pairs = static_cast<int>(pairs.size());
  double samples = 0;
  for (const RowMatrix* x : states) samples += x->rows();
  if (samples * static_cast<double>(pairs.size()) > kMaxPairSamples) return r;

  // the smallest gap beyond its margin of every pair over every sample of every rollout
  std::vector<double> slack(pairs.size(), std::numeric_limits<double>::infinity());
  if (!pairs.empty()) {
    DataPtr data = MakeData(m);
    mjData* d = data.get();
    for (size_t i = 0; i < states.size(); ++i) {
      if (dims.ninput > 0 && i < inputs.size() && inputs[i]->size() == dims.ninput) {
        CallMujoco(
            [&] { mj_setState(&m, d, inputs[i]->data(), static_cast<int>(dims.input_sig)); });
      }
      const RowMatrix& x = *states[i];
      for (int k = 0; k < x.rows(); ++k) {
        SetPhysics(m, d, x.row(k).data());
        CallMujoco([&] { mj_kinematics(&m, d); });
        for (size_t p = 0; p < pairs.size(); ++p) {
          const auto [g1, g2] = pairs[p];
          slack[p] = std::min(slack[p], SphereGap(m, *d, g1, g2) - PairMargin(m, g1, g2));
        }
      }
    }
  }

  // a pair is far when its slack exceeds the clearance; a geom is off when all its pairs are far
  std::vector<char> has_pair(m.ngeom, 0), near(m.ngeom, 0);
  bool all_far = true;
  for (size_t p = 0; p < pairs.size(); ++p) {
    const auto [g1, g2] = pairs[p];
    has_pair[g1] = has_pair[g2] = 1;
    if (!(slack[p] > kReductionClearance)) {
      near[g1] = near[g2] = 1;
      all_far = false;
    }
  }
  if (all_far && m.npair == 0 && m.nflex == 0) {
    // no pair ever comes near: collision off as a whole, every pair watched
    r.disable |= mjDSBL_CONTACT;
    r.watched = pairs;
  } else {
    for (int g = 0; g < m.ngeom; ++g) {
      if (!has_pair[g] || near[g]) continue;
      r.geoms_off.push_back(g);
      r.contype.push_back(m.geom_contype[g]);
      r.conaffinity.push_back(m.geom_conaffinity[g]);
    }
    for (const auto& [g1, g2] : pairs) {
      if ((has_pair[g1] && !near[g1]) || (has_pair[g2] && !near[g2]))
        r.watched.emplace_back(g1, g2);
    }
  }
  r.pairs_off = static_cast<int>(r.watched.size());
  return r;
}

void ApplyReduction(const ModelReduction& r, mjModel* m) {
  m->opt.disableflags |= r.disable;
  for (int g : r.geoms_off) m->geom_contype[g] = m->geom_conaffinity[g] = 0;
}

void RevertReduction(const ModelReduction& r, mjModel* m) {
  m->opt.disableflags &= ~r.disable;
  for (size_t i = 0; i < r.geoms_off.size(); ++i) {
    m->geom_contype[r.geoms_off[i]] = r.contype[i];
    m->geom_conaffinity[r.geoms_off[i]] = r.conaffinity[i];
  }
}

bool ReductionGuardClear(const ModelReduction& r, const mjModel& m, const mjData& d) {
  for (const auto& [g1, g2] : r.watched) {
    if (!(SphereGap(m, d, g1, g2) - PairMargin(m, g1, g2) > 0.5 * kReductionClearance)) {
      return false;
    }
  }
  return true;
}

}  // namespace mjsysid

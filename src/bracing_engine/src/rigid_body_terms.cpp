// The rigid-body terms the model and the law read, in one pass over the joints: pinocchio's computeAllTerms
// cut to what dynamics.cpp and law.cpp use (placements, velocities, the accelerations at ddq = 0, the world
// Jacobians, M, h + g), each by computeAllTerms' own expressions, so they are its numbers bit for bit. Left
// out: dJ, the centroidal terms (Ag, dAg, hg), the centres of mass, g and the energies (make bench's
// engine on the paper arm, four evaluations a step: 88k steps/s with computeAllTerms, 123k with this).
#include <pinocchio/multibody/joint.hpp>
#include <pinocchio/multibody/visitor.hpp>
#include <pinocchio/spatial.hpp>

#include "model.hpp"

namespace bracing_engine {

namespace pin = pinocchio;

namespace {

using ConstRef = Eigen::Ref<const Vector>;

// Joint i, root to tip: its placement, velocity, Jacobian columns, accelerations (a, and a_gf with
// gravity) at ddq = 0, its body's force at those, and its inertia in world axes.
struct ForwardStep : pin::fusion::JointUnaryVisitorBase<ForwardStep> {
  typedef boost::fusion::vector<const pin::Model&, pin::Data&, const ConstRef&, const ConstRef&> ArgsType;

  template <typename JointModel>
  static void algo(const pin::JointModelBase<JointModel>& jmodel,
                   pin::JointDataBase<typename JointModel::JointDataDerived>& jdata, const pin::Model& model,
                   pin::Data& data, const ConstRef& q, const ConstRef& v) {
    const pin::JointIndex i = jmodel.id(), parent = model.parents[i];
    jmodel.calc(jdata.derived(), q, v);
    data.liMi[i] = model.jointPlacements[i] * jdata.M();
    data.v[i] = jdata.v();
    if (parent > 0) {
      data.oMi[i] = data.oMi[parent] * data.liMi[i];
      data.v[i] += data.liMi[i].actInv(data.v[parent]);
    } else {
      data.oMi[i] = data.liMi[i];
    }
    data.oYcrb[i] = data.oMi[i].act(model.inertias[i]);
    jmodel.jointCols(data.J) = data.oMi[i].act(jdata.S());
    data.a_gf[i] = data.a[i] = jdata.c() + (data.v[i] ^ jdata.v());
    if (parent > 0) data.a[i] += data.liMi[i].actInv(data.a[parent]);
    data.a_gf[i] += data.liMi[i].actInv(data.a_gf[parent]);
    data.h[i] = model.inertias[i] * data.v[i];
    data.f[i] = model.inertias[i] * data.a_gf[i] + data.v[i].cross(data.h[i]);
  }
};

// Joint i, tip to root: its rows of M (upper triangle) from its subtree's composite inertia, and h + g.
struct BackwardStep : pin::fusion::JointUnaryVisitorBase<BackwardStep> {
  typedef boost::fusion::vector<const pin::Model&, pin::Data&> ArgsType;

  template <typename JointModel>
  static void algo(const pin::JointModelBase<JointModel>& jmodel,
                   pin::JointDataBase<typename JointModel::JointDataDerived>& jdata, const pin::Model& model,
                   pin::Data& data) {
    const pin::JointIndex i = jmodel.id(), parent = model.parents[i];
    auto J_cols = jmodel.jointCols(data.J);
    auto Ag_cols = jmodel.jointCols(data.Ag);
    pin::motionSet::inertiaAction(data.oYcrb[i], J_cols, Ag_cols);
    data.M.block(jmodel.idx_v(), jmodel.idx_v(), jmodel.nv(), data.nvSubtree[i]).noalias() =
        J_cols.transpose() * data.Ag.middleCols(jmodel.idx_v(), data.nvSubtree[i]);
    jmodel.jointVelocitySelector(data.nle) = jdata.S().transpose() * data.f[i];
    data.oYcrb[parent] += data.oYcrb[i];
    data.f[parent] += data.liMi[i].act(data.f[i]);
  }
};

}  // namespace

void rigid_body_terms(const pin::Model& model, pin::Data& data, const ConstRef& q, const ConstRef& v) {
  if (q.size() != model.nq || v.size() != model.nv) throw std::invalid_argument("rigid_body_terms: wrong size");
  data.v[0].setZero();
  data.a[0].setZero();
  data.h[0].setZero();
  data.a_gf[0] = -model.gravity;
  data.oYcrb[0].setZero();
  for (pin::JointIndex i = 1; i < static_cast<pin::JointIndex>(model.njoints); ++i)
    ForwardStep::run(model.joints[i], data.joints[i], ForwardStep::ArgsType(model, data, q, v));
  for (pin::JointIndex i = static_cast<pin::JointIndex>(model.njoints - 1); i > 0; --i)
    BackwardStep::run(model.joints[i], data.joints[i], BackwardStep::ArgsType(model, data));
  data.M.diagonal() += model.armature;
}

}  // namespace bracing_engine

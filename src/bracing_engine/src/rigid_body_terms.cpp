// The rigid-body terms the model and the law read, in one pass over the joints: pinocchio's computeAllTerms
// cut to what dynamics.cpp and law.cpp use (placements, velocities, the accelerations at ddq = 0, the world
// Jacobians, M, h + g), each by computeAllTerms' own expressions, so they are its numbers bit for bit. Left
// out: dJ, the centroidal terms (Ag, dAg, hg), the centres of mass, g and the energies (make bench's
// engine on the paper arm, four evaluations a step: 88k steps/s with computeAllTerms, 123k with this).
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
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

Wheels wheels_of(const pin::Model& model, const Robot& robot) {
  Wheels wheels;
  if (!robot.rolls()) return wheels;
  if (!(robot.wheel_radius > 0.0)) throw std::invalid_argument("robot.wheel_radius: must be > 0");
  const std::string* names[2] = {&robot.left_wheel, &robot.right_wheel};
  for (int w = 0; w < 2; ++w) {
    if (!model.existJointName(*names[w]) || model.nvs[model.getJointId(*names[w])] != 1)
      throw std::invalid_argument("wheel " + *names[w] + ": not a 1-dof joint of the model");
    wheels.joints[w] = model.getJointId(*names[w]);
  }
  wheels.radius = robot.wheel_radius;
  return wheels;
}

// Each wheel rolls on the plane under its centre without slipping: its contact point, the material point at
// d = -r z below the centre, has no horizontal velocity. v_p = v_c + w x d, so J_p = J_c,lin + r [z]x J_ang;
// its forward part (f = z x l, l the spin axis' horizontal direction) for each wheel and the lateral part
// (along l) of the left one (the right's is the same on a common axle) are the three rows. Their drift:
// d/dt (e . v_p) = e . a_p + de . v_p with a_p = a_c + alpha x d at dv = 0 (d is fixed in the world: the
// contact point is a new material point at each instant) and de from the axis turning with the wheel (da = w x a).
void rolling_rows(const pin::Model& model, pin::Data& data, const Wheels& wheels, const ConstRef& dq,
                  RowMatrix& rows, Vector& drift, pin::Data::Matrix6x& work) {
  const Vector3 up = Vector3::UnitZ(), d = -wheels.radius * up;
  Eigen::Matrix3d up_cross;
  up_cross << 0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0;  // [z]x
  rows.resize(3, model.nv);
  drift.resize(3);
  for (int w = 0; w < 2; ++w) {
    const pin::JointIndex joint = wheels.joints[w];
    work.setZero();
    pin::getJointJacobian(model, data, joint, pin::LOCAL_WORLD_ALIGNED, work);
    const RowMatrix point = work.topRows<3>() + wheels.radius * up_cross * work.bottomRows<3>();
    const Vector3 axis = work.col(model.idx_vs[joint]).tail<3>();  // the spin axis, world
    const Vector3 along = (axis - axis.dot(up) * up).normalized(), forward = up.cross(along);
    const Vector3 omega = pin::getVelocity(model, data, joint, pin::LOCAL_WORLD_ALIGNED).angular();
    const pin::Motion accel = pin::getClassicalAcceleration(model, data, joint, pin::LOCAL_WORLD_ALIGNED);
    const Vector3 point_acceleration = accel.linear() + accel.angular().cross(d);  // d stays below the centre
    const Vector3 turn = omega.cross(axis), along_rate = turn - turn.dot(up) * up;
    const Vector3 velocity = point * dq;
    rows.row(w).noalias() = forward.transpose() * point;
    drift[w] = forward.dot(point_acceleration) + up.cross(along_rate).dot(velocity);
    if (w == 0) {
      rows.row(2).noalias() = along.transpose() * point;
      drift[2] = along.dot(point_acceleration) + along_rate.dot(velocity);
    }
  }
}

}  // namespace bracing_engine

// What the engine's pinocchio files share: the model from the URDF, and the algorithms they call.
#pragma once

#include <pinocchio/algorithm/cholesky.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/multibody/data.hpp>
#include <pinocchio/multibody/model.hpp>

#include "bracing_engine/engine.hpp"

namespace bracing_engine {

class LinkShapes;

// The robot's model from its URDF: gravity set, the locked joints removed at their positions
// (pinocchio's reduced model), `armature` (one value per remaining joint) added to its armature. `shapes`
// (if given and robot.collision_description is not empty): the links' collision shapes on that model.
pinocchio::Model build_model(const Robot& robot, const Vector& armature, LinkShapes* shapes = nullptr);

// What the engine reads of pinocchio's computeAllTerms, its numbers bit for bit (rigid_body_terms.cpp): oMi, v,
// a, a_gf (accelerations at ddq = 0), J (world), M (upper triangle, armature added) and nle = h + g at (q, v).
void rigid_body_terms(const pinocchio::Model& model, pinocchio::Data& data, const Eigen::Ref<const Vector>& q,
                      const Eigen::Ref<const Vector>& v);

// A differential drive's wheel joints in `model` (0: none; robot.left_wheel, right_wheel) and their radius [m].
struct Wheels {
  pinocchio::JointIndex joints[2] = {0, 0};
  double radius = 0.0;
  explicit operator bool() const { return joints[0] != 0; }
};
// The robot's wheels in `model`; throws naming a wheel that is not a 1-dof joint of it.
Wheels wheels_of(const pinocchio::Model& model, const Robot& robot);

// The rolling rows A (3 x n: each wheel's contact point's forward velocity, the left one's lateral) and their
// drift dA dq after rigid_body_terms at (q, dq) (docs/model.md, Differential drive); `work`: 6 x n.
void rolling_rows(const pinocchio::Model& model, pinocchio::Data& data, const Wheels& wheels,
                  const Eigen::Ref<const Vector>& dq, RowMatrix& rows, Vector& drift,
                  pinocchio::Data::Matrix6x& work);

// Mc^-1 R^T by Mc's Cholesky factor (pinocchio::cholesky::decompose done on `data`), one solve per row
// of R: row i of `out` becomes (Mc^-1 R_i^T)^T (pass y.transpose() for an n x k Y). `column`: n of work.
template <typename Rows, typename Out>
void mass_inverse_rows(const pinocchio::Model& model, pinocchio::Data& data, const Eigen::MatrixBase<Rows>& rows,
                       Vector& column, Out&& out) {
  for (Eigen::Index i = 0; i < rows.rows(); ++i) {
    column = rows.row(i).transpose();
    pinocchio::cholesky::solve(model, data, column);
    out.row(i) = column.transpose();
  }
}

// A normal row's W with its sliding friction, W = J_c - mu e^T J: `mu e^T jacobian` taken from `w` (J_c on
// entry), e the unit direction the friction acts against, J the contact's translational Jacobian (3 x n).
// The simulator's rows and the law's alike (docs/model.md).
template <typename Row, typename Jacobian>
void subtract_friction(Row&& w, double mu, const Vector3& e, const Eigen::MatrixBase<Jacobian>& jacobian) {
  w.noalias() -= mu * (e.transpose() * jacobian);
}

// The translational Jacobian (3 x n, world axes at the frame: the top rows of `work`, a 6 x n frame
// Jacobian) of `frame` after rigid_body_terms.
inline auto translational_jacobian(const pinocchio::Model& model, pinocchio::Data& data, pinocchio::FrameIndex frame,
                                   pinocchio::Data::Matrix6x& work) {
  work.setZero();
  pinocchio::getFrameJacobian(model, data, frame, pinocchio::LOCAL_WORLD_ALIGNED, work);
  return work.topRows<3>();
}

}  // namespace bracing_engine

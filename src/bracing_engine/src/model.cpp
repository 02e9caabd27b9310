// The robot's pinocchio model from its URDF (the one place the URDF parser is compiled).
#include "model.hpp"

#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/model.hpp>
#include <pinocchio/parsers/urdf.hpp>

namespace bracing_engine {

namespace pin = pinocchio;

std::string compiled_pinocchio_version() { return PINOCCHIO_VERSION; }

namespace {

// `full` with the locked joints removed at their positions (pinocchio's reduced model).
pin::Model locked(const pin::Model& full, const Robot& robot) {
  Eigen::VectorXd reference = pin::neutral(full);
  std::vector<pin::JointIndex> joints;
  for (std::size_t k = 0; k < robot.locked_joints.size(); ++k) {
    const auto& name = robot.locked_joints[k];
    if (!full.existJointName(name)) throw std::invalid_argument("robot.locked_joints: no joint " + name);
    const auto joint = full.getJointId(name);
    reference[full.idx_qs[joint]] = k < robot.locked_positions.size() ? robot.locked_positions[k] : 0.0;
    joints.push_back(joint);
  }
  return pin::buildReducedModel(full, joints, reference);
}

}  // namespace

pin::Model build_model(const Robot& robot, const Vector& armature) {
  pin::Model full;
  if (robot.urdf_xml.empty())
    pin::urdf::buildModel(robot.urdf_path, full);
  else
    pin::urdf::buildModelFromXML(robot.urdf_xml, full);
  full.gravity.linear(robot.gravity);
  pin::Model model = robot.locked_joints.empty() ? full : locked(full, robot);
  if (model.nq != model.nv) throw std::invalid_argument("only 1-dof revolute/prismatic joints are supported");
  if (armature.size() != model.nv) throw std::invalid_argument("drive: one value per joint expected");
  model.armature += armature;
  if (robot.mass_scale != 1.0) {
    for (auto& inertia : model.inertias) {
      pin::Inertia::Symmetric3 rotational = inertia.inertia();
      rotational.data() *= robot.mass_scale;
      inertia = pin::Inertia(robot.mass_scale * inertia.mass(), inertia.lever(), rotational);
    }
  }
  return model;
}

}  // namespace bracing_engine

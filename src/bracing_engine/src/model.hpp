// What the engine's pinocchio files share: the model from the URDF, and the algorithms they call.
#pragma once

#include <pinocchio/algorithm/cholesky.hpp>
#include <pinocchio/algorithm/compute-all-terms.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/multibody/data.hpp>
#include <pinocchio/multibody/model.hpp>

#include "bracing_engine/engine.hpp"

namespace bracing_engine {

// The robot's model from its URDF: gravity set, the locked joints removed at their positions
// (pinocchio's reduced model), `armature` (one value per remaining joint) added to its armature.
pinocchio::Model build_model(const Robot& robot, const Vector& armature);

}  // namespace bracing_engine

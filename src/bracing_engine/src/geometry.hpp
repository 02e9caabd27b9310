// The links' collision shapes (the URDF's <collision> elements, pinocchio's GeometryModel on coal) measured
// against the contact surfaces, and the contacts whose point is where their link's shapes are nearest their
// surface (`point: geometry`). Only geometry.cpp and model.cpp compile coal.
#pragma once

#include <pinocchio/multibody/data.hpp>
#include <pinocchio/multibody/model.hpp>

#include <memory>
#include <string>
#include <vector>

#include "bracing_engine/engine.hpp"

namespace bracing_engine {

// The point of a set of shapes nearest a surface (deepest inside it when they cross it).
struct Witness {
  double distance = 0.0;             // C at the point [m] (< 0: inside)
  Vector3 point = Vector3::Zero();   // world [m]
  Vector3 normal = Vector3::Zero();  // the surface's n there
  int shape = -1;                    // which shape of the geometry model
};

// The collision shapes of a model that move (not those fixed to the world), grouped by link; each mesh measured
// by its convex hull (exact against a plane, whose nearest point of a body is a vertex of its hull).
class LinkShapes {
 public:
  LinkShapes();
  ~LinkShapes();
  LinkShapes(LinkShapes&&) noexcept;
  LinkShapes& operator=(LinkShapes&&) noexcept;

  // From the URDF text (robot.collision_description) on `full`, reduced as `model` was (the locked joints at
  // their positions). Throws std::invalid_argument naming a mesh that cannot be read.
  void build(const pinocchio::Model& full, const Robot& robot, const std::vector<pinocchio::JointIndex>& locked,
             const Eigen::VectorXd& reference, const pinocchio::Model& model);
  bool empty() const;
  // The links that have shapes, in model frame order.
  const std::vector<std::string>& links() const;
  // The shapes of link `k` of links().
  const std::vector<int>& shapes_of(int k) const;
  // The shapes of the body `frame` is on: its own link's, else those of the links it is fixed to (walking up
  // fixed joints, never across a moving one); empty if none has any.
  std::vector<int> shapes_of_frame(const pinocchio::Model& model, pinocchio::FrameIndex frame) const;
  // The joint the shapes move with.
  pinocchio::JointIndex joint_of(int shape) const;
  // Throws std::invalid_argument if `surface` is one coal cannot measure these shapes against (`what` names them).
  static void check_surface(const Surface& surface, const std::string& what);
  // The point of `shapes` nearest `surface` (data.oMi current: after rigid_body_terms or forwardKinematics).
  Witness nearest(const pinocchio::Data& data, const std::vector<int>& shapes, const Surface& surface) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The contacts with `point: geometry`: each has a frame of its own on its link's joint, moved before each use to
// where the link's shapes are nearest its surface. Every reader of the frame (its placement, its Jacobian, its
// classical acceleration: the contact rows and gamma) then takes the contact at that point.
//
// Approximation of the moving point: within one evaluation the point is a material point of the link, so
// gamma = n . (dJ dq) is the acceleration of that material point at ddq = 0. Exact for a flat face, an edge or a
// vertex on a plane (the point does not move on the body while it stays the nearest); for a smooth curved shape
// rolling on a plane (a cylinder's side, a sphere, a capsule) it leaves out n . (w x dp/dt), dp/dt the point's
// speed over the body, which is second order in the rolling rate; the point is re-found at every evaluation, so
// the residual C, and with it the Baumgarte term, are exact at each one.
class GeometryPoints {
 public:
  // Adds a frame to `model` per contact of `contacts` with `geometry` (its index stored in `frames`), the
  // shapes from `shapes`. Throws std::invalid_argument naming a contact whose link has no shape or whose surface
  // coal cannot measure.
  void attach(pinocchio::Model& model, const LinkShapes& shapes, const std::vector<Contact>& contacts,
              std::vector<pinocchio::FrameIndex>& frames);
  bool empty() const { return entries_.empty(); }
  // Each geometry contact's frame moved to its witness point (data.oMi current).
  void place(pinocchio::Model& model, const pinocchio::Data& data) const;

 private:
  struct Entry {
    pinocchio::FrameIndex frame;
    std::vector<int> shapes;
    Surface surface;
  };
  const LinkShapes* shapes_ = nullptr;
  std::vector<Entry> entries_;
};

void measure_links(const LinkShapes& shapes, const pinocchio::Data& data, const std::vector<Surface>& surfaces,
                   LinkMeasurement& out);

}  // namespace bracing_engine

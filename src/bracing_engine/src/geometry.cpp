// The links' collision shapes against the contact surfaces, by coal: against a plane its halfspace distance's own
// support point along -n (closed form for a primitive, a mesh by its convex hull), against a sphere its distance.
#include "geometry.hpp"

#include <coal/BVH/BVH_model.h>
#include <coal/distance.h>
#include <coal/narrowphase/support_functions.h>
#include <coal/shape/geometric_shapes.h>

#include <pinocchio/algorithm/model.hpp>
#include <pinocchio/collision/coal-pinocchio-conversions.hpp>
#include <pinocchio/geometry.hpp>
#include <pinocchio/parsers/urdf.hpp>

#include <algorithm>
#include <limits>
#include <map>
#include <sstream>

namespace bracing_engine {

namespace pin = pinocchio;

struct LinkShapes::Impl {
  pin::GeometryModel geometry;
  std::vector<std::shared_ptr<coal::CollisionGeometry>> measured;  // per shape: itself, or a mesh's convex hull
  std::vector<std::string> links;
  std::vector<pin::FrameIndex> link_frames;
  std::vector<std::vector<int>> link_shapes;
};

LinkShapes::LinkShapes() : impl_(std::make_unique<Impl>()) {}
LinkShapes::~LinkShapes() = default;
LinkShapes::LinkShapes(LinkShapes&&) noexcept = default;
LinkShapes& LinkShapes::operator=(LinkShapes&&) noexcept = default;

namespace {

// What coal measures a shape by: a mesh by its convex hull (qhull), any other shape itself.
std::shared_ptr<coal::CollisionGeometry> measured_shape(const pin::GeometryObject& object) {
  auto* mesh = dynamic_cast<coal::BVHModelBase*>(object.geometry.get());
  if (!mesh) {
    if (!dynamic_cast<const coal::ShapeBase*>(object.geometry.get()))
      throw std::invalid_argument("robot.collision_geometry: " + object.name +
                                  " is a shape coal cannot measure against a surface (a box, cylinder, sphere, "
                                  "capsule or mesh can be)");
    return object.geometry;
  }
  if (mesh->num_vertices < 4)
    throw std::invalid_argument("robot.collision_geometry: the mesh " + object.meshPath + " of " + object.name +
                                " has fewer than 4 vertices");
  if (!mesh->convex) {
    try {
      mesh->buildConvexHull(false, "Qt");
    } catch (const std::exception& exc) {
      throw std::invalid_argument("robot.collision_geometry: no convex hull of the mesh " + object.meshPath + " of " +
                                  object.name + ": " + exc.what());
    }
  }
  return mesh->convex;
}

// coal's solid for a sphere surface (the robot stays outside it).
std::shared_ptr<coal::CollisionGeometry> surface_solid(const Surface& surface) {
  return std::make_shared<coal::Sphere>(surface.radius);
}

}  // namespace

void LinkShapes::build(const pin::Model& full, const Robot& robot, const std::vector<pin::JointIndex>& locked,
                       const Eigen::VectorXd& reference, const pin::Model& model) {
  Impl& m = *impl_;
  pin::GeometryModel all;
  std::istringstream xml(robot.collision_description);
  try {
    pin::urdf::buildGeom(full, xml, pin::COLLISION, all);
  } catch (const std::exception& exc) {
    throw std::invalid_argument(std::string("robot.collision_geometry: the URDF's collision shapes cannot be read: ") +
                                exc.what());
  }
  if (locked.empty()) {
    m.geometry = all;
  } else {
    pin::Model reduced;
    pin::buildReducedModel(full, all, locked, reference, reduced, m.geometry);
  }
  std::map<pin::FrameIndex, int> link_of_frame;
  for (std::size_t k = 0; k < m.geometry.geometryObjects.size(); ++k) {
    const auto& object = m.geometry.geometryObjects[k];
    // A shape fixed to the world (the root link, a link past locked joints) cannot move into or out of a
    // surface: not measured, as MuJoCo collides no world-body geom with the world's planes.
    if (object.parentJoint == 0) {
      m.measured.emplace_back();
      continue;
    }
    if (!object.geometry)
      throw std::invalid_argument("robot.collision_geometry: " + object.name + " has no shape coal can measure");
    m.measured.push_back(measured_shape(object));
    auto found = link_of_frame.find(object.parentFrame);
    if (found == link_of_frame.end()) {
      found = link_of_frame.emplace(object.parentFrame, static_cast<int>(m.links.size())).first;
      m.links.push_back(model.frames[object.parentFrame].name);
      m.link_frames.push_back(object.parentFrame);
      m.link_shapes.emplace_back();
    }
    m.link_shapes[found->second].push_back(static_cast<int>(k));
  }
}

bool LinkShapes::empty() const { return impl_->links.empty(); }
const std::vector<std::string>& LinkShapes::links() const { return impl_->links; }
const std::vector<int>& LinkShapes::shapes_of(int k) const { return impl_->link_shapes[k]; }

pin::JointIndex LinkShapes::joint_of(int shape) const { return impl_->geometry.geometryObjects[shape].parentJoint; }

std::vector<int> LinkShapes::shapes_of_frame(const pin::Model& model, pin::FrameIndex frame) const {
  const Impl& m = *impl_;
  const pin::JointIndex joint = model.frames[frame].parentJoint;
  // up the frame tree from `frame` to the first body with shapes, staying on the frame's joint
  for (pin::FrameIndex f = frame;; f = model.frames[f].parentFrame) {
    const auto found = std::find(m.link_frames.begin(), m.link_frames.end(), f);
    if (found != m.link_frames.end()) return m.link_shapes[found - m.link_frames.begin()];
    if (f == 0 || model.frames[f].type == pin::JOINT || model.frames[f].parentJoint != joint) return {};
  }
}

void LinkShapes::check_surface(const Surface& surface, const std::string& what) {
  if (surface.kind == SurfaceKind::plane || (surface.kind == SurfaceKind::sphere && !surface.inside)) return;
  throw std::invalid_argument(what + ": coal measures collision shapes against a plane or the outside of a sphere, "
                                     "not the " +
                              std::string(surface.kind == SurfaceKind::cylinder ? "cylinder" : "inside of a sphere") +
                              " surface: use point: frame there");
}

Witness LinkShapes::nearest(const pin::Data& data, const std::vector<int>& shapes, const Surface& surface) const {
  const Impl& m = *impl_;
  Witness best;
  best.distance = std::numeric_limits<double>::infinity();
  std::shared_ptr<coal::CollisionGeometry> solid;  // a sphere's: coal's distance (GJK)
  coal::DistanceRequest request;
  request.enable_signed_distance = true;
  for (int k : shapes) {
    const auto& object = m.geometry.geometryObjects[k];
    const pin::SE3 placement = data.oMi[object.parentJoint] * object.placement;
    Vector3 point;
    if (surface.kind == SurfaceKind::plane) {
      // coal's halfspace distance itself: the shape's support point along -n (closed form for a primitive,
      // hill climbing on a convex hull's vertices, from vertex 0 every time: a function of the posture alone)
      int hint = 0;
      const Vector3 along = -(placement.rotation().transpose() * surface.normal);
      const auto* shape = static_cast<const coal::ShapeBase*>(m.measured[k].get());
      point = placement.act(Vector3(coal::details::getSupport<coal::details::WithSweptSphere>(shape, along, hint)));
    } else {
      if (!solid) solid = surface_solid(surface);
      coal::DistanceResult result;
      coal::distance(m.measured[k].get(), pin::toCoalTransform3s(placement), solid.get(),
                     coal::Transform3s(Matrix3::Identity(), surface.center), request, result);
      point = result.nearest_points[0];
    }
    // C at the witness: the surface's own signed distance, the same number the contact rows use
    double c;
    Vector3 n;
    Matrix3 hessian;
    surface.evaluate(point, c, n, hessian);
    if (c < best.distance) best = {c, point, n, k};
  }
  return best;
}

void GeometryPoints::attach(pin::Model& model, const LinkShapes& shapes, const std::vector<Contact>& contacts,
                            std::vector<pin::FrameIndex>& frames) {
  shapes_ = &shapes;
  for (std::size_t j = 0; j < contacts.size(); ++j) {
    const Contact& contact = contacts[j];
    if (!contact.geometry) continue;
    const std::string what = "contacts." + contact.name + ".point: geometry";
    LinkShapes::check_surface(contact.surface, what);
    std::vector<int> own = shapes.shapes_of_frame(model, frames[j]);
    if (own.empty())
      throw std::invalid_argument(what + ": the link of frame " + contact.frame +
                                  " has no collision shapes in the URDF: give it a <collision> element, or use point: "
                                  "frame");
    const pin::JointIndex joint = shapes.joint_of(own.front());
    frames[j] = model.addFrame(pin::Frame(contact.name + " point", joint, frames[j], pin::SE3::Identity(), pin::OP_FRAME),
                               false);
    entries_.push_back({frames[j], std::move(own), contact.surface});
  }
}

void GeometryPoints::place(pin::Model& model, const pin::Data& data) const {
  for (const Entry& entry : entries_) {
    const Witness witness = shapes_->nearest(data, entry.shapes, entry.surface);
    auto& frame = model.frames[entry.frame];
    frame.placement = pin::SE3(Matrix3::Identity(), data.oMi[frame.parentJoint].actInv(witness.point));
  }
}

void measure_links(const LinkShapes& shapes, const pin::Data& data, const std::vector<Surface>& surfaces,
                   LinkMeasurement& out) {
  const int links = static_cast<int>(shapes.links().size()), rows = links * static_cast<int>(surfaces.size());
  out.links = shapes.links();
  out.distance.resize(rows);
  out.points.resize(rows, 3);
  out.normals.resize(rows, 3);
  for (std::size_t s = 0; s < surfaces.size(); ++s) {
    for (int k = 0; k < links; ++k) {
      const int row = static_cast<int>(s) * links + k;
      const Witness witness = shapes.nearest(data, shapes.shapes_of(k), surfaces[s]);
      out.distance[row] = witness.distance;
      out.points.row(row) = witness.point.transpose();
      out.normals.row(row) = witness.normal.transpose();
    }
  }
}

}  // namespace bracing_engine

// The surfaces a contact point meets, C(r) >= 0 free (docs/model.md, Contacts), and a point's
// kinematics on its surface, shared by the model and the law:
//
//   gamma = n . (dJ dq) + v^T H v,   slip = v - n (n . v)
#include <cmath>

#include "bracing_engine/engine.hpp"

namespace bracing_engine {

void Surface::evaluate(const Vector3& r, double& c, Vector3& n, Matrix3& h) const {
  if (kind == SurfaceKind::plane) {
    c = normal.dot(r) - offset;
    n = normal;
    h.setZero();
    return;
  }
  // A sphere (projector I) or a cylinder (I - a a^T): with d the distance to the centre (axis),
  // n = offset / d and H = (projector - n n^T) / d; inside, all three change sign.
  Matrix3 projector = Matrix3::Identity();
  if (kind == SurfaceKind::cylinder) projector -= axis * axis.transpose();
  const Vector3 away = projector * (r - center);
  const double distance = away.norm();
  if (distance < 1e-12)
    throw std::domain_error("a contact point is at the centre of its sphere or on the axis of its cylinder");
  n = away / distance;
  h = (projector - n * n.transpose()) / distance;
  c = distance - radius;
  if (inside) {
    c = -c;
    n = -n;
    h = -h;
  }
}

ContactPoint contact_point(const Surface& surface, const Vector3& position, const Vector3& velocity,
                           const Vector3& acceleration) {
  ContactPoint point;
  Matrix3 hessian;
  surface.evaluate(position, point.residual, point.normal, hessian);
  point.drift = point.normal.dot(acceleration);
  if (surface.kind != SurfaceKind::plane) point.drift += velocity.dot(hessian * velocity);
  point.slip = velocity - point.normal * point.normal.dot(velocity);
  return point;
}

}  // namespace bracing_engine

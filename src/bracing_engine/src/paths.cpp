// The task paths (bracing_core.trajectory.TrajectoryConfig): a hold, a circle, and waypoints on the
// minimum-jerk profile.
#include <cmath>

#include "bracing_engine/law.hpp"

namespace bracing_engine {

namespace {

// Python's float floor division (t // step), so a segment switches at the same sample.
double floor_div(double t, double step) {
  double mod = std::fmod(t, step);
  double div = (t - mod) / step;
  if (mod != 0.0 && ((step < 0.0) != (mod < 0.0))) div -= 1.0;
  double floor_value = std::floor(div);
  if (div - floor_value > 0.5) floor_value += 1.0;
  return floor_value;
}

}  // namespace

// With a start ramp T the reference starts where the task point is, at rest. The path's own time runs as
// tau(t) = T (x^3 - x^4 / 2), x = t / T, until T, then t - T / 2 (tau' = 3 x^2 - 2 x^3 rises from 0 to 1 with
// zero slope at both ends), and the offset from the first measured position to the path's start fades on
// the minimum-jerk profile 1 - s(x): no step in position or speed for the law's first update to answer.
void Path::sample(const Vector3& start, double t, Vector3& position, Vector3& velocity) const {
  if (!(start_ramp > 0.0)) {
    sample_at(start, t, position, velocity);
    return;
  }
  if (t >= start_ramp) {
    sample_at(start, t - 0.5 * start_ramp, position, velocity);
    return;
  }
  const double x = t > 0.0 ? t / start_ramp : 0.0;
  sample_at(start, start_ramp * x * x * x * (1.0 - 0.5 * x), position, velocity);
  velocity *= x * x * (3.0 - 2.0 * x);
  Vector3 origin, unused;
  sample_at(start, 0.0, origin, unused);
  const Vector3 offset = start - origin;
  const double s = x * x * x * (10.0 + x * (-15.0 + 6.0 * x));
  position += (1.0 - s) * offset;
  velocity -= 30.0 * x * x * (1.0 - x) * (1.0 - x) / start_ramp * offset;
}

void Path::sample_at(const Vector3& start, double t, Vector3& position, Vector3& velocity) const {
  velocity.setZero();
  switch (kind) {
    case PathKind::hold:
      position = has_point ? point : start;
      return;
    case PathKind::circle: {
      const double rate = direction * 2.0 * M_PI / period;
      const double angle = rate * t + phase;
      position = center;
      position[u] += radius * std::cos(angle);
      position[v] += radius * std::sin(angle);
      velocity[u] = -radius * rate * std::sin(angle);
      velocity[v] = radius * rate * std::cos(angle);
      return;
    }
    case PathKind::waypoints: {
      // rest to rest through each waypoint, minimum jerk s(x) = 10 x^3 - 15 x^4 + 6 x^5 per segment
      const long segment = t > 0.0 ? static_cast<long>(floor_div(t, segment_time)) : 0;
      const long count = static_cast<long>(waypoints.size());
      if (segment >= count) {
        position = count ? waypoints.back() : start;
        return;
      }
      const double x = t / segment_time - static_cast<double>(segment);
      const double s = x * x * x * (10.0 + x * (-15.0 + 6.0 * x));
      const double ds = 30.0 * x * x * (1.0 - x) * (1.0 - x) / segment_time;
      const Vector3& a = segment ? waypoints[segment - 1] : start;
      const Vector3& b = waypoints[segment];
      position = a + s * (b - a);
      velocity = ds * (b - a);
      return;
    }
  }
}
}  // namespace bracing_engine

// The bracing engine: the constrained robot + motor-circuit model (docs/model.md) and its RK4
// integrator. pinocchio stays behind Dynamics' pimpl, so only dynamics.cpp pays its compile time.
#pragma once

#include <Eigen/Core>

#include <cmath>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace bracing_engine {

using Vector = Eigen::VectorXd;
using Vector3 = Eigen::Vector3d;
using Matrix3 = Eigen::Matrix3d;
using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using Mask = std::vector<bool>;

// The contact forces are not determined: the constraint rows have no effect on the motion.
struct SingularError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Sim time: a state's time is its stamp, an integer count of nanoseconds (the simulator node stamps
// state k with k * step_ns), read in seconds through this one conversion by whatever reads it: the
// controller node's law (the stamp of the state it answers), the rollout, the Python Simulator. Two
// roundings of one instant (k * h against k * step_ns * 1e-9) differ by an ulp at a quarter of the
// 1 ms steps, and a redundant arm's null space grows such an ulp (docs/model.md, Lockstep).
inline double stamp_seconds(std::int64_t ns) { return static_cast<double>(ns) * 1e-9; }
// [ns] the stamp increment of a step of `step` seconds.
inline std::int64_t step_nanoseconds(double step) { return std::llround(step * 1e9); }

// The pinocchio version the engine was compiled against (its headers).
std::string compiled_pinocchio_version();

enum class SurfaceKind { plane = 0, sphere = 1, cylinder = 2 };

// C(r) >= 0 is free; n = dC/dr is unit; H is C's Hessian (zero for a plane).
struct Surface {
  SurfaceKind kind = SurfaceKind::plane;
  Vector3 normal = Vector3::UnitZ();  // plane: C = n . r - offset
  double offset = 0.0;
  Vector3 center = Vector3::Zero();  // sphere centre, or a point on a cylinder's axis
  Vector3 axis = Vector3::UnitZ();   // cylinder
  double radius = 0.0;
  bool inside = false;  // sphere/cylinder: the robot stays inside, C = radius - distance

  // C, n and H at point r (throws std::domain_error at a sphere's centre or on a cylinder's axis).
  void evaluate(const Vector3& r, double& c, Vector3& n, Matrix3& h) const;
};

// A contact point's kinematics on its surface: what the model's and the law's contact rows are built from.
struct ContactPoint {
  double residual = 0.0;             // C
  Vector3 normal = Vector3::Zero();  // n at the point
  Vector3 slip = Vector3::Zero();    // the tangential velocity v - n (n . v)
  double drift = 0.0;                // gamma = n . (dJ dq) + v^T H v
};

// The point at `position` moving with `velocity` (J dq) and classical acceleration (dJ dq), world axes.
ContactPoint contact_point(const Surface& surface, const Vector3& position, const Vector3& velocity,
                           const Vector3& acceleration);

struct Contact {
  std::string name;
  std::string frame;
  Surface surface;
  double friction = 0.0;    // mu
  bool unilateral = false;  // only pushes; releases and lands
  bool enforced = true;     // false: only watched, never holds a force
  // Coulomb friction: stick held by two tangential constraint rows while |f_t| <= mu |f_n|, slide
  // with |f_t| = mu |f_n| against the slip; false: the paper's regularised law
  // f_t = mu f_n s / sqrt(|s|^2 + eps^2).
  bool coulomb = false;
};

// A slip speed [m/s] below which a Coulomb contact's slip has no direction of its own (it slides
// along its stored direction).
constexpr double kSlipAtRest = 1e-10;

// The contacts' modes: which hold a normal force, which of those stick (Coulomb), and for a
// Coulomb contact sliding: the slip direction d to use while the slip is at rest (right after a
// breakaway: where the holding force pushed it), and the sign of f_n (+1: pushing), held over a
// step, so the sliding friction f_t = -mu |f_n| d is linear in f_n.
struct ContactModes {
  Mask held, sticking;
  RowMatrix slide;  // p x 3: d
  Vector pushing;   // p: +1 or -1
};

// What builds the pinocchio model: the URDF, gravity and the joints held still.
struct Robot {
  std::string urdf_path;
  Vector3 gravity = Vector3(0.0, 0.0, -9.81);
  std::vector<std::string> locked_joints;
  std::vector<double> locked_positions;
  // Every moving link's mass and rotational inertia times this (plant_error.mass_scale: a plant that
  // differs from the controller's model; 1 leaves the URDF's numbers untouched).
  double mass_scale = 1.0;
  // The URDF text to build from instead of the file's (bracing_core.base.chart_urdf: continuous joints as
  // unlimited revolute ones, a planar root as base_x, base_y, base_yaw); empty: the file at urdf_path.
  std::string urdf_xml;
  // A differential drive (robot.base: diff_drive): the left and right wheel joints (empty: none) and their
  // radius [m]. The planar root (base_x, base_y, base_yaw) then moves only as the wheels roll without
  // slipping on the plane z = const: the rolling rows (Dynamics) beside the contacts.
  std::string left_wheel, right_wheel;
  double wheel_radius = 0.0;
  bool rolls() const { return !left_wheel.empty(); }
};

// Per joint, model order. Voltage mode: drive = K_m i, Mc = M + J_m, Dc = D + D_m, and
// L di = v - R(T) i - K_m dq. Torque mode: drive = tau, Mc = M, Dc = D, no circuit.
// Thermal (voltage mode): one winding temperature T per motor, C_th dT/dt = R(T) i^2 - (T - T_a) / R_th,
// R(T) = R_20 (1 + alpha (T - 20 degC)); off, R = R_20 and T stays at T_a.
struct Drive {
  bool voltage = true;
  Vector added_inertia;      // Mc - M (J_m, or zeros)
  Vector damping;            // Dc
  Vector torque_constant;    // K_m [N m / A]
  Vector resistance;         // R_20 [ohm], at 20 degC
  Vector inductance;         // L [H]
  Vector reflected_damping;  // D_m (the effort the link sees is K_m i - D_m dq - J_m ddq)
  bool thermal = false;
  Vector thermal_resistance;    // R_th, winding to ambient [K/W]
  Vector heat_capacity;         // C_th [J/K]
  double ambient = 20.0;        // T_a [degC], also every winding's temperature at the start
  double temperature_coefficient = 0.00393;  // alpha [1/K] (copper)

  // R(T) [ohm] per motor (R_20 when the thermal model is off).
  void resistance_at(const Eigen::Ref<const Vector>& temperature, Vector& out) const {
    if (thermal)
      out = (resistance.array() * (1.0 + temperature_coefficient * (temperature.array() - 20.0))).matrix();
    else
      out = resistance;
  }
};

// The model's answer at one state. Forces are zero for contacts not held; the contact terms
// are every contact's when the answer is full (rows in contact order).
struct Answer {
  Vector ddq, di, force, effort;
  Vector resistance;              // R(T) the circuit used [ohm]
  double friction_power = 0.0;    // sum mu f_n (dir . slip) [W]
  double constraint_power = 0.0;  // sum f_n (J_c dq) [W]
  RowMatrix positions;            // p x 3
  RowMatrix jacobians;            // 3p x n: contact j's translational Jacobian in rows 3j..3j+2
  RowMatrix normal_jacobian;      // p x n, rows n^T J
  RowMatrix tangent_jacobian;     // p x n, rows dir^T J
  RowMatrix slip;                 // p x 3, tangential velocity
  RowMatrix direction;            // p x 3, slip / sqrt(|slip|^2 + eps^2)
  RowMatrix normals;              // p x 3, n at the point
  Vector drift;                   // gamma = n . (dJ dq) + v^T H v
  Vector residual;                // C
  RowMatrix tangential_force;     // p x 3, the friction force on the robot [N]
  Vector friction;                // p: |f_t| of a Coulomb contact, mu f_n of a regularised one [N]
  // A differential drive's rolling rows A v (the left and right wheels' contact points' forward velocities, the
  // left one's lateral velocity) [m/s]: zero without slip; and their forces [N] (the ground on the wheels).
  Vector rolling_velocity, rolling_force;
};

class Dynamics {
 public:
  Dynamics(const Robot& robot, const Drive& drive, std::vector<Contact> contacts, double slip_epsilon,
           double baumgarte);
  ~Dynamics();
  Dynamics(const Dynamics&) = delete;
  Dynamics& operator=(const Dynamics&) = delete;

  int nv() const;
  int contact_count() const;
  const std::vector<Contact>& contacts() const;
  const Drive& drive() const;
  std::vector<std::string> joint_names() const;
  double baumgarte = 0.0;  // a [1/s]: J_c ddq = -gamma - 2 a J_c dq - a^2 C (rolling rows: A dv = -dA v - 2 a A v)
  int rolling_rows() const;  // 3 with a differential drive, else 0

  // ddq, di, f_n at (q, dq, i, T) with input u held, the contacts in `held` holding forces. `full`:
  // also every contact's terms. Throws SingularError.
  void evaluate(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& dq,
                const Eigen::Ref<const Vector>& current, const Eigen::Ref<const Vector>& temperature,
                const Eigen::Ref<const Vector>& u, const ContactModes& modes, bool full, Answer& out) const;
  // The circuit's part of `out` (di, the effort, R(T)) redone under input u, `out` being an answer at
  // (q, dq, i, T) under another input. Voltage mode only: the rest of the answer does not depend on u there.
  void rerun_circuit(const Eigen::Ref<const Vector>& dq, const Eigen::Ref<const Vector>& current,
                     const Eigen::Ref<const Vector>& temperature, const Eigen::Ref<const Vector>& u,
                     Answer& out) const;
  // Every contact's terms at (q, dq), no solve (force, ddq and di untouched).
  void terms(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& dq, Answer& out) const;
  // Newton steps in the metric of Mc onto C = 0 for the contacts `rows`; throws std::domain_error
  // naming the contacts if 50 steps do not bring every |C| under `tolerance`.
  Vector project(const Vector& q, const std::vector<int>& rows, double tolerance = 1e-13) const;
  // Inelastic, frictionless impact of the contacts `rows` at (q, dq): q is put on the surfaces and
  // their normal velocity removed with the impulse Mc^-1 J_c^T lambda. Returns the kinetic energy lost.
  double impact(Vector& q, Vector& dq, const std::vector<int>& rows) const;
  // The velocity dq projected onto the held constraints of `modes` (normal rows of the held contacts,
  // tangential rows of the sticking ones) by an impulse Mc^-1 R^T lambda: as a contact starts to stick.
  // Returns the kinetic energy lost.
  double hold_velocity(const Vector& q, Vector& dq, const ContactModes& modes) const;
  // The tangent directions (orthonormal, at most 2, in the plane normal to n) along which a frame
  // with translational Jacobian `jacobian` can move: a sticking contact's rows are t^T J for these
  // (a planar arm's contact has one; a direction no joint moves would make the rows singular).
  static int tangent_directions(const Vector3& n, const Eigen::Ref<const RowMatrix>& jacobian, Vector3 out[2]);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

enum class EventKind { release = 0, touchdown = 1, stick = 2, slip = 3 };

struct ContactEvent {
  long step;       // the step count when it happened
  double offset;   // [s] into that step (stick and slip are located inside a step)
  int contact;     // index in the contact list
  EventKind kind;
  double energy_loss;  // [J]: a touchdown's impact loss, the impulse that makes a contact stick
};

enum class StepStatus { ok = 0, diverged = 1, joint_limit = 2 };

// Why the simulator node refuses a step it took (Simulator::refusal): none; non-finite forces or slip; a
// joint faster than the speed limit; a held contact further than the residual limit off its surface; a
// winding hotter than kWindingTemperatureLimit.
enum class Refusal { none = 0, non_finite = 3, too_fast = 4, off_surface = 5, too_hot = 6 };

// The energy integrals appended to the state, in this order (simulator.py ENERGY_KEYS): consumed |P|, net P
// (P = v i, or tau dq in torque mode), copper loss R(T) i^2, viscous loss dq^T Dc dq, friction loss,
// constraint work, impact loss (events only).
namespace energy {
enum Slot : int { consumed, net, copper_loss, viscous_loss, friction_loss, constraint_work, impact_loss };
}  // namespace energy
constexpr int kEnergies = 7;
// The state y = [q, dq, i, T, energies]: kStates blocks of n (T, the winding temperatures [degC], is
// integrated with the circuit it heats and before the integrals, so the event location's Hermite
// interpolant carries it with the rest of the motion).
constexpr int kStates = 4;
// [degC] A winding hotter than this is refused, as a joint faster than divergence_speed is: copper melts
// at 1085 degC and insulation fails near 200 degC, so no motor gets there (an absurd voltage does, and
// R(T) / L would then make the circuit too stiff for RK4 at any later step).
constexpr double kWindingTemperatureLimit = 1000.0;

// Classic RK4 with the input held over a step (sub-steps of step / substeps), the energy
// integrals integrated with the state, unilateral release (at a step's start) and touchdown (at
// its end), Coulomb stick and slip (events located inside a step), the joint-limit stop and the
// divergence check.
class Simulator {
 public:
  Simulator(std::shared_ptr<const Dynamics> dynamics, double step, int substeps, const Vector& q0,
            const Vector& dq0, const Vector& lower_limits, const Vector& upper_limits);

  // Advances one step with u held. On ok, `report` is the model at the step's start (every
  // contact's terms); otherwise the state and the modes are unchanged and `failed_joint` names a limit.
  StepStatus step(const Vector& u);
  // `report` = the model at the current state under u (no time passes).
  void evaluate(const Vector& u);
  // Whether the simulator node refuses the step just taken (`report` its answer at the step's
  // start, the state the new one), see Refusal. `measured`: the speed (too_fast), the temperature
  // (too_hot) or the largest held |C| (otherwise).
  Refusal refusal(double speed_limit, double residual_limit, double& measured) const;
  void set_active(const Mask& active);
  void set_modes(const ContactModes& modes);
  void set_state(const Vector& y);  // [q, dq, i, T, energies]
  void truncate_events(std::size_t count);

  const Dynamics& dynamics() const { return *dynamics_; }
  int nv() const { return n_; }
  double step_size() const { return step_; }
  std::int64_t step_ns() const { return step_nanoseconds(step_); }  // [ns] what each step adds to the stamp
  int substeps() const { return substeps_; }
  const Vector& state() const { return y_; }
  const Mask& active() const { return modes_.held; }
  const ContactModes& modes() const { return modes_; }
  const ContactModes& report_modes() const { return report_modes_; }  // the modes `report` was made in
  bool all_active() const;
  const std::vector<ContactEvent>& events() const { return events_; }
  // Where the energy integral `slot` is in the state.
  Eigen::Index energy_index(energy::Slot slot) const { return kStates * n_ + slot; }
  // Voltage input: the windings start at the steady current of the first step's command (i = (u - K_m dq) / R(T),
  // set as that step starts), as a drive that is powered and holding when the run starts; false: i = 0.
  bool steady_start = false;
  // The windings' currents set to their steady value under u at the current state (voltage input).
  void hold_current(const Vector& u);
  long steps_taken = 0;
  Answer report;
  int failed_joint = -1;         // the joint a refused step would have taken past its limit
  double failed_position = 0.0;  // where

 private:
  // The modes at the step's start under u: unilateral contacts that pull release, Coulomb contacts
  // whose holding force leaves the cone slide; `report` is the model there.
  void start(const Vector& u);
  // The modes at the start (q0, dq0): Coulomb contacts at rest stick, moving ones slide along their slip.
  void initial_modes(const Vector& q0, const Vector& dq0);
  // Unilateral contacts whose force in `report` would pull let go, the most negative first; true if one did.
  bool release_pulling();
  // A sliding Coulomb contact's friction follows the sign of its normal force in `report`; true if one flipped.
  bool follow_force_signs();
  // Breakaways at the current state (report evaluated there); true if a contact changed mode.
  bool break_away(double offset);
  // How far sticking contact j's holding force in `answer` is outside the cone |f_t| <= mu |f_n| (> 0:
  // outside, beyond rounding).
  double cone_excess(const Answer& answer, int j) const;
  // The switch to slipping: sticking contact j slides along where its holding force in `answer` held it
  // back from (d = -f_t / |f_t|, the sign of f_n held), an event `offset` [s] into the step.
  void start_sliding(int j, const Answer& answer, double offset);
  // One sub-step of size h from y with events located inside it; `first`: `report` is its first stage.
  void advance(Vector& y, double h, const Vector& u, bool first, double offset);
  // An interval's start at y: y0_, the first stage's rates k_[0], e_[0]; the model there (`report` if first).
  const Answer& open_interval(const Vector& y, const Vector& u, bool first);
  // The sliding Coulomb contacts' slip directions at an interval's start (their stored one while at rest).
  void hold_slide_directions(const Answer& opening);
  // The first event inside (0, span] of the interval from y0_ to y1_ (k_first_, k_end_ its end rates):
  // its contact (-1: none) and time `when`.
  int first_event(double span, const Vector& u, double& when);
  // The time in (0, span] where contact j's event function crosses zero, on the step's cubic Hermite
  // interpolant (Illinois method), just past the crossing.
  double locate(int j, double span, const Vector& u);
  // Contact j's mode switched at state y, `at` [s] into the step: a sticking one slides; a sliding one
  // sticks (its slip impulsively removed), and slides on at once if its forces cannot hold it.
  void switch_mode(int j, Vector& y, const Vector& u, double at);
  // One RK4 step of size h from y0 into y1; stage 1's rates are in k_[0], e_[0].
  void rk4(const Vector& y0, double h, const Vector& u, Vector& y1);
  // The event functions of the held Coulomb contacts from an answer at a state (>= 0: no event).
  void event_functions(const Answer& answer, Vector& g) const;
  // Released contacts that reached their surface while approaching land (inelastic impact).
  void touchdown();
  // The sticking contacts' drifted tangential velocity projected back to zero at a step's end.
  void hold_sticking();
  // Whether located_, the model at the step's end, is `report` for the next step's start but for its
  // circuit (voltage input: ddq and the forces do not depend on u): the state, the modes and the gain unchanged.
  bool end_reusable() const;
  // The model at state x = [q, dq, i, T, ...] under u with the current contact modes (`full`: every
  // contact's terms too): the one place a state is cut into the model's arguments.
  void evaluate_at(const Eigen::Ref<const Vector>& x, const Vector& u, bool full, Answer& out) const;
  // The rates [dq, ddq, di, dT] and the energy rates at stage state x (`evaluated`: `answer` is already
  // the model there).
  void rates(const Eigen::Ref<const Vector>& x, const Vector& u, bool evaluated, Answer& answer, Vector& k,
             Vector& e) const;

  std::shared_ptr<const Dynamics> dynamics_;
  int n_, p_;
  double step_;
  int substeps_;
  Vector lower_, upper_;
  Vector y_, y_next_;  // q, dq, i, T, energies (a step writes the next into y_next_ and swaps)
  ContactModes modes_, report_modes_;
  ContactModes start_modes_;  // a step's modes at its start, restored if it is refused
  Mask unilateral_, enforced_, coulomb_;
  bool any_unilateral_ = false, any_coulomb_ = false;
  bool end_evaluated_ = false;  // located_ holds the model at the state the last step ended in
  double end_baumgarte_ = 0.0;  // the Baumgarte gain located_ was evaluated with
  std::vector<ContactEvent> events_;
  Answer stage_, located_;  // the later stages' answers; the model at a step's end or a trial event time
  Vector x_, y0_, y1_, k_[4], e_[4], k_end_, e_end_, k_first_, e_first_;
  Vector g_start_, g_end_, g_trial_;  // event functions per contact
  RowMatrix start_direction_;  // p x 3: the Coulomb contacts' slip directions at an interval's start
};

}  // namespace bracing_engine

"""Pure numerics (numpy + pinocchio, never rclpy): robot model, motors, contacts,
constrained dynamics, integrator. Shared by the simulator node, the controller,
the tests and the benchmarks."""

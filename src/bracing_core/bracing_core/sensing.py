"""How the simulated arm differs from what its controller is told: the plant's model error
(``plant_error.*``) and what its sensors measure (``sensors.*``). Light: the pair plans runs with it
without loading pinocchio or the engine.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from bracing_core import schema
from bracing_core.schema import Values

if TYPE_CHECKING:
    import bracing_engine as engine
    from bracing_core.schema.typed_values import SimulatorValues, SimulatorValuesPlantError, SimulatorValuesSensors
else:  # the classes the schema derives (tools/values_stubs.py declares them to mypy)
    SimulatorValuesPlantError = schema.NODE_VALUES["simulator"].sections["plant_error"]
    SimulatorValuesSensors = schema.NODE_VALUES["simulator"].sections["sensors"]


class PlantError(SimulatorValuesPlantError):
    """plant_error.*: how the simulated plant differs from the scenario (the controller's model); a field per
    parameter of ``schema.PLANT_ERROR``, urdf the plant's own URDF resolved (empty: robot.urdf)."""

    @property
    def none(self) -> bool:
        """The plant is the scenario's: every number as it was."""
        return schema.at_defaults(self)


GROUND_TRUTH = "ground_truth/"
"""With sensors that are not exact, the simulator publishes the truth under this prefix too
(``ground_truth/joint_states``, ``ground_truth/motor_state``): the bag holds what the controller
received and what was true."""


class SensorConfig(SimulatorValuesSensors):
    """sensors.*: what the simulator publishes as measured; a field per parameter of ``schema.SENSORS`` (units in
    the names)."""

    @classmethod
    def from_values(cls, values: Values[SimulatorValues]) -> SensorConfig:
        """From the simulator's schema values (``schema.read``)."""
        return cls(**schema.fields_of(values.params.sensors))

    @property
    def exact(self) -> bool:
        """Exact and instant (the paper's sensing): the seed alone changes nothing."""
        return schema.at_defaults(self, but=("noise_seed",))

    def engine(self, step: float, prismatic: Sequence[bool]) -> engine.Sensors:
        """The engine's sensors for joints that are ``prismatic`` (not on the encoder's angular grid)."""
        import bracing_engine as engine

        spec = engine.SensorSpec(
            step=step,
            revolute=[not p for p in prismatic],
            seed=self.noise_seed,
            encoder_counts_per_rev=self.encoder_counts_per_rev,
            position_noise=self.position_noise_rad,
            velocity_noise=self.velocity_noise_rad_s,
            velocity_filter_hz=self.velocity_filter_hz,
            force_noise=self.force_noise_n,
            force_bias=self.force_bias_n,
            current_noise=self.current_noise_a,
            command_latency_steps=self.command_latency_steps,
        )
        return engine.Sensors(spec, len(prismatic))

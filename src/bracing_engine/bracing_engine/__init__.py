"""The compiled engine (C++ on pinocchio, docs/model.md): ``Dynamics`` evaluates the constrained
robot + motor-circuit model, ``Simulator`` integrates it (RK4, energy integrals, unilateral
contacts), ``Law`` is the decoupled control law with its task ``Path``s, and ``rollout`` runs the
closed loop (law + simulator) for many steps without coming back to Python; ``Sensors`` is what a
real arm's controller measures and how late its commands land. Specifications cross whole, by keyword
(``Robot``, ``Drive``, ``LawSpec``, ``SensorSpec``); answers as structures with named fields (``Answer``,
``StepResult``, ``Advance``: the simulator node's step, ``State``, ``LawOutput``, ``Recording``, ``ContactEvent``,
``ContactModes``), kinds as
enums (``StepStatus``, ``Refusal``, ``EventKind``, ``PathKind``, ``EnergySlot``). ``check_command`` is the motor
command's value rule (finite, saturated to the limits: ``CommandCheck``) of both of the simulator's command paths,
the C++ one through ``command_api`` (as ``state_refusal`` and ``law_api`` serve the controller's). The build writes the
module's type stubs (``_engine.pyi``, nanobind's stub generator): mypy checks every call into it. ``bracing_core``'s
dynamics, simulator, law and trajectory modules are its readable Python face."""

import pinocchio  # first: the engine links the libpinocchio this loads (one copy in the process)

from bracing_engine._engine import (
    PINOCCHIO_VERSION,
    WINDING_TEMPERATURE_LIMIT,
    Advance,
    Answer,
    BracedContact,
    CommandCheck,
    Contact,
    ContactEvent,
    ContactModes,
    Drive,
    Dynamics,
    EnergySlot,
    EventKind,
    Law,
    LawOutput,
    LawSpec,
    LinkMeasurement,
    OrientationTask,
    Path,
    PathKind,
    Recording,
    Refusal,
    Robot,
    Sensors,
    SensorSpec,
    Simulator,
    SingularError,
    State,
    StepResult,
    StepStatus,
    Surface,
    Task,
    check_command,
    command_api,
    law_api,
    rollout,
    stamp_seconds,
    state_refusal,
)

if PINOCCHIO_VERSION != pinocchio.__version__:
    raise ImportError(
        f"bracing_engine was compiled against pinocchio {PINOCCHIO_VERSION} but pinocchio {pinocchio.__version__} "
        "is installed: run 'make setup' to rebuild it"
    )

__all__ = [
    "WINDING_TEMPERATURE_LIMIT",
    "Advance",
    "Answer",
    "BracedContact",
    "CommandCheck",
    "Contact",
    "ContactEvent",
    "ContactModes",
    "Drive",
    "Dynamics",
    "EnergySlot",
    "EventKind",
    "Law",
    "LawOutput",
    "LawSpec",
    "LinkMeasurement",
    "OrientationTask",
    "Path",
    "PathKind",
    "Recording",
    "Refusal",
    "Robot",
    "SensorSpec",
    "Sensors",
    "Simulator",
    "SingularError",
    "State",
    "StepResult",
    "StepStatus",
    "Surface",
    "Task",
    "check_command",
    "command_api",
    "law_api",
    "rollout",
    "stamp_seconds",
    "state_refusal",
]

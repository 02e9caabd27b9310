"""The compiled engine (C++ on pinocchio, docs/model.md): ``Dynamics`` evaluates the constrained
robot + motor-circuit model, ``Simulator`` integrates it (RK4, energy integrals, unilateral
contacts). ``bracing_core.dynamics`` and ``bracing_core.simulator`` are its readable Python face."""

import pinocchio  # first: the engine links the libpinocchio this loads (one copy in the process)

from bracing_engine._engine import (
    PINOCCHIO_VERSION,
    Contact,
    Drive,
    Dynamics,
    Robot,
    Simulator,
    SingularError,
    Surface,
)

if PINOCCHIO_VERSION != pinocchio.__version__:
    raise ImportError(
        f"bracing_engine was compiled against pinocchio {PINOCCHIO_VERSION} but pinocchio {pinocchio.__version__} "
        "is installed: run 'make setup' to rebuild it"
    )

__all__ = ["Contact", "Drive", "Dynamics", "Robot", "Simulator", "SingularError", "Surface"]

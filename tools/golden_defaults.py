"""Fingerprints of every shipped scenario's closed loop with its file's own parameters, written to
test/data/golden_defaults.json; test_robustness_knobs.py checks that the knobs off by default leave
them bit for bit as they were.

    python tools/golden_defaults.py > test/data/golden_defaults.json   (only when a change of the numbers is meant)
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np

from bracing_core.rollout import build_scenario, run_recorded

CONFIG = Path(__file__).resolve().parent.parent / "config"
FIELDS = (
    "time", "position", "velocity", "current", "temperature", "command", "hand_desired", "hand_actual",
    "brace_desired", "brace_actual", "contact_position", "slip_velocity", "normal_force", "friction_force",
    "residual", "energy_consumed", "energy_net", "copper_loss",
)  # fmt: skip
CASES = [(path.stem, mode) for path in sorted(CONFIG.glob("*.yaml")) for mode in ("voltage", "torque")]
DURATION_S = 0.3


def fingerprint(scenario: str, mode: str) -> dict[str, object]:
    """sha256 of the recorded arrays' bytes, and the final state's numbers as text (for a reader)."""
    recording = run_recorded(build_scenario(CONFIG / f"{scenario}.yaml", shared={"input_mode": mode}), DURATION_S)
    digest = hashlib.sha256()
    for name in FIELDS:
        digest.update(np.ascontiguousarray(getattr(recording, name), dtype=float).tobytes())
    return {"sha256": digest.hexdigest(), "final_position": [repr(float(v)) for v in recording.position[-1]]}


def main() -> int:
    out = {f"{scenario}:{mode}": fingerprint(scenario, mode) for scenario, mode in CASES}
    json.dump({"duration_s": DURATION_S, "cases": out}, sys.stdout, indent=1)
    print()
    return 0


if __name__ == "__main__":
    sys.exit(main())

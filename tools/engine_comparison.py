"""Our engine against MuJoCo: the paper scenario, torque input, 2 s, run by bracing-pair on each engine (``--engine
mujoco`` and ours), compared from the two bags; printed as a table and, with ``--record FILE``, written as a recorded
file (bracing_experiments.recorded: with the date, commit and machine) that the results page renders
(tools/docs_reference.py). test_mujoco_robot.py makes the same two runs (``PAIR_ARGS``) and checks ``figures``.

    python tools/engine_comparison.py [--output DIR] [--record docs/results/data/engine_comparison.json]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from bracing_analysis.bag import read_series
from bracing_analysis.series import BagSeries
from bracing_core.numbers import markdown_table
from bracing_experiments.recorded import write_recorded

ROOT = Path(__file__).resolve().parents[1]
PAIR_ARGS = ("--duration", "2", "--mode", "torque", "--no-animation")
"""bracing-pair's arguments for both runs (the paper scenario, the file's)."""
SETTLED_S = 0.2
"""[s] From this time on MuJoCo's soft contact has settled (the sphere sunk in to carry f_nd)."""
TABLE = "engine-comparison"


def run_pair(output: Path, engine: str | None, env: dict[str, str] | None = None) -> dict[str, Any]:
    """bracing-pair on the paper scenario with ``PAIR_ARGS`` (``engine``: ``mujoco`` or None for ours); its
    summary.json."""
    argv = [sys.executable, "-m", "bracing_bringup.pair", "--config", str(ROOT / "config" / "paper_4link.yaml")]
    argv += ["--output", str(output), "--quiet", *PAIR_ARGS, *(["--engine", engine] if engine else [])]
    done = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=300, cwd=ROOT)
    if done.returncode != 0:
        raise SystemExit(f"bracing-pair {engine or 'bracing'} failed:\n{done.stdout}{done.stderr}")
    summary: dict[str, Any] = json.loads((output / "summary.json").read_text())
    return summary


def _hand_errors(series: BagSeries) -> np.ndarray:
    return np.asarray(np.linalg.norm(series.hand_desired - series.hand_actual, axis=1))


def _path_length(series: BagSeries, contact: str) -> float:
    """[m] How far the contact point travelled along the surface (the sum of its steps)."""
    position = series.contacts[contact].position
    return float(np.sum(np.linalg.norm(np.diff(position, axis=0), axis=1)))


def engine_figures(series: BagSeries, summary: dict[str, Any], contact: str = "elbow") -> dict[str, float]:
    """One run's figures: hand error RMS over the run and at its end [m], f_n - f_nd RMS and largest from
    ``SETTLED_S`` [N], the deepest penetration [m], the contact point's path [m]."""
    hand, cs = _hand_errors(series), series.contacts[contact]
    force = cs.normal_force_error[np.isfinite(cs.normal_force_error)]
    late = cs.normal_force_error[(cs.t_matched >= SETTLED_S) & np.isfinite(cs.normal_force_error)]
    return {
        "hand_rms_m": float(np.sqrt(np.mean(hand**2))),
        "hand_end_m": float(hand[-1]),
        "force_rms_n": float(np.sqrt(np.mean(force**2))),
        "force_late_max_n": float(np.max(np.abs(late))),
        "penetration_m": float(summary["max_penetration_m"]),
        "contact_path_m": _path_length(series, contact),
    }


def figures(mujoco: Path, ours: Path) -> dict[str, Any]:
    """Both runs' figures (``engine_figures``) and the largest distance of MuJoCo's hand from ours at a common
    controller stamp, with its time."""
    from bracing_analysis.wrench_contacts import contacts_from_wrenches

    theirs, base = read_series(mujoco / "bag"), read_series(ours / "bag")
    contacts_from_wrenches(theirs)
    summaries = [json.loads((run / "summary.json").read_text()) for run in (mujoco, ours)]
    _, here, there = np.intersect1d(np.round(theirs.t, 6), np.round(base.t, 6), return_indices=True)
    apart = np.linalg.norm(theirs.hand_actual[here] - base.hand_actual[there], axis=1)
    k = int(np.argmax(apart))
    return {
        "ours": engine_figures(base, summaries[1]),
        "mujoco": engine_figures(theirs, summaries[0]),
        "hand_apart_max_m": float(apart[k]),
        "hand_apart_at_s": float(theirs.t[here][k]),
        "common_stamps": int(here.size),
    }


def comparison_table(found: dict[str, Any]) -> dict[str, list[Any]]:
    """The results page's table: a row per figure, our engine's and MuJoCo's."""
    ours, theirs = found["ours"], found["mujoco"]

    def row(name: str, *keys: str) -> list[str]:
        return [name, " / ".join(f"{ours[k]:.4g}" for k in keys), " / ".join(f"{theirs[k]:.4g}" for k in keys)]

    rows = [
        row("hand error, RMS over the run / at its end [m]", "hand_rms_m", "hand_end_m"),
        [
            "hand, largest distance from our engine's path [m]",
            "",
            f"{found['hand_apart_max_m']:.2g} (at t = {found['hand_apart_at_s']:.3g} s)",
        ],
        row("f_n - f_nd, RMS over the run [N]", "force_rms_n"),
        row(f"f_n - f_nd, largest from t = {SETTLED_S:g} s [N]", "force_late_max_n"),
        row("elbow penetration, deepest [m]", "penetration_m"),
        row("elbow's path along the floor [m]", "contact_path_m"),
    ]
    version = metadata.version("mujoco")
    return {"header": ["", "our engine", f"MuJoCo {version}"], "rows": rows}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--output", type=Path, default=Path("out/engine_comparison"), help="the two runs' directory")
    parser.add_argument("--record", type=Path, metavar="FILE", help="also write the table as a recorded file")
    args = parser.parse_args(argv)
    for engine, name in (("mujoco", "mujoco"), (None, "bracing")):
        run_pair(args.output / name, engine)
    found = figures(args.output / "mujoco", args.output / "bracing")
    print(markdown_table(**comparison_table(found)))
    if args.record is not None:
        print(f"recorded: {record_comparison(args.record, found)}")
    return 0


def record_comparison(path: Path, found: dict[str, Any]) -> Path:
    """``figures``' answer and its table as the recorded file ``path``."""
    content = {"study": "engine comparison", "config": "paper_4link.yaml", "figures": found}
    return write_recorded(path, {**content, "tables": {TABLE: comparison_table(found)}}, ROOT)


if __name__ == "__main__":
    sys.exit(main())

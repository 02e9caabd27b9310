"""bracing-study: the paper's comparisons as one report, from in-process runs in parallel.

    bracing-study paper --output DIR [--duration S] [--workers N] [--scheduler ADDRESS] [--set KEY=VALUE ...]
    bracing-study config/hyper_7link.yaml --output DIR

1. bracing: braced vs free (no contacts), voltage and torque input, with and without
   null-space gravity compensation: hand RMS / max error, energy consumed, copper loss;
2. gains: every PD gain (hand and brace, Kp and Kd) scaled by 1, 0.5, 0.2, 0.1, torque and
   voltage input: force error (max, RMS) against the position errors (paper Sec. 4, Figs. 9-16);
3. placement: energy and hand error over a grid of brace targets along the first brace axis of
   the first contact and of desired normal forces, the best cell marked.

Writes DIR/report.md with its figures (bracing.png, gains.png, placement.png), and the sweep's
DIR/results.parquet, DIR/results.csv and DIR/runs/ (the same command again reuses finished runs).
Exit 0 when every run is ok, 1 when one failed (the report is still written, its cells say which),
2 on a configuration error before any run (every run's configuration and task rank are checked first).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bracing_bringup.executors import make_executor
from bracing_bringup.experiment import FORCE_MAX_ERROR_KEY, STATUS_FAILED, STATUS_OK, RunSpec
from bracing_bringup.overrides import CONTROLLER, parse_single, route
from bracing_bringup.ratios import ratio
from bracing_bringup.summary import HAND_ERROR_T_MIN_S
from bracing_bringup.sweep import (
    ARRAYS_FILE,
    EXIT_CONFIG,
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    ResultsStore,
    any_failed,
    handle_stop_signals,
    make_spec,
    row_warnings,
    run_sweep,
)
from bracing_core import schema
from bracing_core.config import SharedConfig
from bracing_core.params import ConfigError, load_params_file, resolve_file

SCENARIO_ALIASES = {"paper": "paper_4link.yaml"}
PAPER_SCENARIO = "paper_4link"
"""The scenario whose figures the paper has: only its report cites them."""
GAIN_SCALES = (1.0, 0.5, 0.2, 0.1)
FORCE_SCALES = (0.5, 1.0, 2.0)  # x the file's desired normal force
REPORT = "report.md"


@dataclass
class Study:
    config: Path
    duration: float | None
    bracing: list[RunSpec]
    gains: list[RunSpec]
    placement: list[RunSpec]
    contact: str  # the placement study's contact
    axis: str  # ... and the brace axis its targets move along
    targets: list[float]  # [m] along that axis
    forces: list[float]  # [N]

    @property
    def specs(self) -> list[RunSpec]:
        return [*self.bracing, *self.gains, *self.placement]

    @property
    def scenario(self) -> str:
        return self.config.stem

    def paper(self, text: str) -> str:
        """``text`` (a citation of the paper's figures) for the paper's scenario, else nothing."""
        return text if self.scenario == PAPER_SCENARIO else ""


def resolve_scenario(name: str) -> Path:
    """``paper`` or a scenario file (a path, or a name in the config directories)."""
    path = Path(name)
    if path.is_file():
        return path
    file = SCENARIO_ALIASES.get(name, name if name.endswith((".yaml", ".yml")) else f"{name}.yaml")
    return resolve_file(file, "scenario", [Path.cwd() / "config"])


def _scaled(values: Any, scale: float) -> list[float]:
    return [float(v) * scale for v in (values if isinstance(values, list) else [values])]


def build_study(
    config: Path,
    duration: float | None = None,
    base: dict[str, Any] | None = None,
    positions: int = 5,
    span: float = 0.15,
    force_scales: Sequence[float] = FORCE_SCALES,
    gain_scales: Sequence[float] = GAIN_SCALES,
) -> Study:
    """Every run of the three comparisons, validated. ``base``: overrides applied to all runs."""
    from bracing_core.rollout import build_scenario

    base = dict(base or {})
    routed = route(base)
    ctl = {**load_params_file(config, CONTROLLER), **routed.for_node(CONTROLLER)}
    shared = SharedConfig.from_values(schema.read("controller", ctl), [config.resolve().parent])
    braced = [c for c in shared.contacts if c.brace_axes and c.desired_normal_force]
    if not braced:
        raise ConfigError("contacts.names: the study needs a bracing contact (one with brace_axes and a desired force)")

    def spec(comparison: str, labels: dict[str, Any], overrides: dict[str, Any]) -> RunSpec:
        return make_spec(config, {"comparison": comparison, **labels}, duration, overrides={**base, **overrides})

    bracing = [
        spec(
            "bracing",
            {"bracing": with_contacts, "input_mode": mode, "gravity_compensation": compensation},
            {
                "input_mode": mode,
                "gravity_compensation": compensation,
                **({} if with_contacts else {"contacts.names": []}),
            },
        )
        for with_contacts in (True, False)
        for mode in ("voltage", "torque")
        for compensation in (False, True)
    ]
    gains = []
    for mode in ("torque", "voltage"):
        for scale in gain_scales:
            gain_overrides: dict[str, Any] = {
                "input_mode": mode,
                "hand.kp": _scaled(ctl["hand.kp"], scale),
                "hand.kd": _scaled(ctl["hand.kd"], scale),
            }
            for contact in shared.contacts:
                for gain in ("kp", "kd"):
                    key = f"contacts.{contact.name}.{gain}"
                    gain_overrides[key] = _scaled(ctl.get(key, []), scale)
            gains.append(spec("gains", {"input_mode": mode, "gain_scale": scale}, gain_overrides))

    contact = braced[0]
    axis = contact.brace_axes[0]
    scenario = build_scenario(config, shared=routed.shared, sim=routed.simulator, with_controller=False)
    start = scenario.sim.evaluate(np.zeros(scenario.sim.n)).contacts.positions
    origin = np.array(contact.target if contact.target is not None else start[shared.contacts.index(contact)])
    offsets = np.linspace(-span, span, positions) if positions > 1 else np.zeros(1)
    targets = [float(origin[axis] + d) for d in offsets]
    desired = contact.desired_normal_force
    assert desired is not None  # a braced contact (study_specs picks one)
    forces = [desired * s for s in force_scales]
    placement = []
    for force in forces:
        for target in targets:
            point = origin.copy()
            point[axis] = target
            placement.append(
                spec(
                    "placement",
                    {"brace_target": round(target, 6), "desired_normal_force": force},
                    {
                        f"contacts.{contact.name}.target": [float(v) for v in point],
                        f"contacts.{contact.name}.desired_normal_force": force,
                    },
                )
            )
    return Study(config, duration, bracing, gains, placement, contact.name, "xyz"[axis], targets, forces)


# -- the report ------------------------------------------------------------------------------------
def _fmt(value: Any, digits: int = 4) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def _table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_fmt(v) for v in row) + " |" for row in rows]
    return "\n".join(lines)


def _arrays(store: ResultsStore, run_id: str) -> dict[str, np.ndarray] | None:
    path = store.run_dir(run_id) / ARRAYS_FILE
    if not path.is_file():
        return None
    with np.load(path) as data:
        return {key: data[key] for key in data.files}


def _ok(row: dict[str, Any] | None) -> bool:
    return row is not None and row.get("status") == STATUS_OK


def _bracing_section(study: Study, store: ResultsStore, rows: dict[str, dict[str, Any]]) -> list[str]:
    header = ["bracing", "input", "gravity comp.", "hand RMS [m]", "hand max [m]", "energy [J]", "copper loss [J]"]
    table, lookup = [], {}
    for spec in study.bracing:
        row = rows.get(spec.run_id)
        v = spec.varied
        lookup[(v["bracing"], v["input_mode"], v["gravity_compensation"])] = row
        labels = [v["bracing"], v["input_mode"], v["gravity_compensation"]]
        if row is not None and _ok(row):
            keys = ("hand_rms_error_m", "hand_max_error_m", "energy_consumed_j", "copper_loss_j")
            table.append([*labels, *(row.get(k) for k in keys)])
        else:
            table.append([*labels, f"failed: {row.get('error') if row else 'not run'}", "", "", ""])
    ratios = []
    findings = []
    for mode in ("voltage", "torque"):
        for compensation in (False, True):
            braced, free = lookup.get((True, mode, compensation)), lookup.get((False, mode, compensation))
            if not (_ok(braced) and _ok(free)):
                continue
            assert braced is not None and free is not None
            energy = ratio("energy_consumed_j", braced, free)[0]
            hand = ratio("hand_rms_error_m", braced, free)[0]
            ratios.append([mode, compensation, energy, hand])
            if hand is not None and energy is not None:
                better = "more precise" if hand < 1 else "less precise"
                findings.append(
                    f"{mode} input, {'with' if compensation else 'without'} gravity compensation: bracing uses "
                    f"{energy:.3g} x the energy and the hand is {better} (RMS error x {hand:.3g})."
                )
    lines = [
        "## 1. Braced vs free",
        "",
        "The same hand task with the contact (braced) and without any (free), for both input modes,",
        f"with and without gravity compensation in the null space. Hand errors over t >= {HAND_ERROR_T_MIN_S:g} s.",
        "",
        _table(header, table),
        "",
        _table(["input", "gravity comp.", "energy braced / free", "hand RMS braced / free"], ratios),
        "",
        *[f"- {line}" for line in findings],
        "",
        "![hand error and energy over time, braced and free](bracing.png)",
        "",
    ]
    _draw_bracing(study, store, rows)
    return lines


def _draw_bracing(study: Study, store: ResultsStore, rows: dict[str, dict[str, Any]]) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 4.2), layout="constrained")
    fig.suptitle(f"{study.scenario}: braced vs free")
    error_ax, energy_ax = fig.subplots(1, 2)
    colours = {
        ("voltage", False): "tab:blue",
        ("voltage", True): "tab:cyan",
        ("torque", False): "tab:red",
        ("torque", True): "tab:orange",
    }
    for spec in study.bracing:
        if not _ok(rows.get(spec.run_id)):
            continue
        data = _arrays(store, spec.run_id)
        if data is None:
            continue
        v = spec.varied
        gravity = "g comp." if v["gravity_compensation"] else "no g comp."
        label = f"{'braced' if v['bracing'] else 'free'}, {v['input_mode']}, {gravity}"
        style = dict(color=colours[(v["input_mode"], v["gravity_compensation"])], ls="-" if v["bracing"] else "--")
        error = np.linalg.norm(data["hand_desired"] - data["hand_actual"], axis=1)
        error_ax.plot(data["time"], error, label=label, lw=1.2, **style)
        energy_ax.plot(data["time"], data["energy_consumed"], label=label, lw=1.2, **style)
    error_ax.set(title="hand error |r_hd - r_h|", xlabel="time [s]", ylabel="[m]", yscale="log")
    energy_ax.set(title="energy consumed (torque input: mechanical)", xlabel="time [s]", ylabel="[J]", yscale="log")
    for ax in (error_ax, energy_ax):
        ax.grid(True, alpha=0.4)
    energy_ax.legend(fontsize=7, loc="upper left")
    fig.savefig(store.output / "bracing.png", dpi=110)


def _gains_section(study: Study, store: ResultsStore, rows: dict[str, dict[str, Any]]) -> list[str]:
    header = [
        "input",
        "gain scale",
        "force max err [N]",
        "force RMS err [N]",
        "hand RMS [m]",
        "hand max [m]",
        "brace RMS [m]",
    ]
    table = []
    worst: dict[str, float] = {}
    for spec in study.gains:
        row = rows.get(spec.run_id)
        v = spec.varied
        if not _ok(row):
            table.append([v["input_mode"], v["gain_scale"], f"failed: {row.get('error') if row else 'not run'}"])
            continue
        assert row is not None
        keys = (
            FORCE_MAX_ERROR_KEY,
            "normal_force_rms_error_n",
            "hand_rms_error_m",
            "hand_max_error_m",
            "brace_rms_error_m",
        )
        table.append([v["input_mode"], v["gain_scale"], *(row.get(k) for k in keys)])
        force = row.get(FORCE_MAX_ERROR_KEY)
        if isinstance(force, (int, float)):
            worst[v["input_mode"]] = max(worst.get(v["input_mode"], 0.0), float(force))
    findings = []
    if "torque" in worst:
        findings.append(
            f"Torque input: the largest force error over every gain scale is {worst['torque']:.2g} N "
            "(machine precision: f_n = f_nd every step, eq. 40), while the position errors grow as the gains drop."
        )
    if "voltage" in worst:
        early, late = _voltage_force_errors(study, store, rows)
        findings.append(
            f"Voltage input: the force error reaches {early:.3g} N in the initial transient (t < "
            f"{HAND_ERROR_T_MIN_S:g} s) and at most {late:.3g} N after it: the law sets voltages, and the "
            "motor currents (hence torques) lag them through L and the back-EMF; the position errors grow as with "
            "torque input."
        )
    lines = [
        "## 2. Gains: position and force are decoupled",
        "",
        "All PD gains (hand and brace, Kp and Kd) scaled together, braced"
        + study.paper(", paper Sec. 4 / Figs. 9-16")
        + ".",
        "",
        _table(header, table),
        "",
        *[f"- {line}" for line in findings],
        "",
        "![force error against position errors as the gains drop](gains.png)",
        "",
    ]
    _draw_gains(study, store, rows)
    return lines


def _voltage_force_errors(study: Study, store: ResultsStore, rows: dict[str, dict[str, Any]]) -> tuple[float, float]:
    """max |f_n - f_nd| [N] over the voltage-input gain runs: in the transient (t < 2 s) and after."""
    early, late = 0.0, 0.0
    for spec in study.gains:
        if spec.varied["input_mode"] != "voltage" or not _ok(rows.get(spec.run_id)):
            continue
        data = _arrays(store, spec.run_id)
        if data is None or not data["normal_force"].size:
            continue
        error = np.max(np.abs(data["normal_force"] - data["desired_normal_force"]), axis=1)
        after = data["time"] >= HAND_ERROR_T_MIN_S - 1e-9
        early = max(early, float(np.max(error[~after], initial=0.0)))
        late = max(late, float(np.max(error[after], initial=0.0)))
    return early, late


def _draw_gains(study: Study, store: ResultsStore, rows: dict[str, dict[str, Any]]) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(14, 4.2), layout="constrained")
    fig.suptitle(f"{study.scenario}: gains scaled together")
    force_ax, position_ax, series_ax = fig.subplots(1, 3)
    colours = {"torque": "tab:red", "voltage": "tab:blue"}
    for mode in ("torque", "voltage"):
        points = [
            (s.varied["gain_scale"], rows[s.run_id])
            for s in study.gains
            if s.varied["input_mode"] == mode and _ok(rows.get(s.run_id))
        ]
        if not points:
            continue
        scales = [p[0] for p in points]
        force = [max(float(p[1].get(FORCE_MAX_ERROR_KEY) or 0.0), 1e-16) for p in points]
        force_ax.plot(scales, force, "o-", color=colours[mode], label=f"{mode}: max |f_n - f_nd|")
        for key, marker, name in (("hand_rms_error_m", "o-", "hand RMS"), ("brace_rms_error_m", "s--", "brace RMS")):
            position_ax.plot(
                scales, [p[1].get(key) for p in points], marker, color=colours[mode], label=f"{mode}: {name}"
            )
    for spec in study.gains:
        if spec.varied["input_mode"] != "voltage" or not _ok(rows.get(spec.run_id)):
            continue
        data = _arrays(store, spec.run_id)
        if data is not None and data["normal_force"].size:
            series_ax.plot(
                data["time"], data["normal_force"][:, 0], lw=1.0, label=f"voltage, x{spec.varied['gain_scale']:g}"
            )
            desired = float(data["desired_normal_force"][0])
    if series_ax.lines:
        series_ax.axhline(desired, color="tab:red", ls="--", lw=1.0, label="f_nd (torque input: every run)")
    force_ax.axhline(np.finfo(float).eps * 10, color="grey", ls=":", lw=1.0)
    force_ax.set(
        title="force error (torque input: machine precision)",
        xlabel="gain scale",
        ylabel="[N]",
        xscale="log",
        yscale="log",
    )
    position_ax.set(title="position errors", xlabel="gain scale", ylabel="[m]", xscale="log")
    series_ax.set(title="normal force, voltage input" + study.paper(" (Fig. 16)"), xlabel="time [s]", ylabel="f_n [N]")
    for ax in (force_ax, position_ax, series_ax):
        ax.grid(True, alpha=0.4)
        ax.legend(fontsize=7)
    fig.savefig(store.output / "gains.png", dpi=110)


def _placement_section(study: Study, store: ResultsStore, rows: dict[str, dict[str, Any]]) -> list[str]:
    grids = {
        key: np.full((len(study.forces), len(study.targets)), np.nan)
        for key in ("energy_consumed_j", "hand_rms_error_m", "brace_rms_error_m")
    }
    failed = []
    for k, spec in enumerate(study.placement):
        i, j = divmod(k, len(study.targets))
        row = rows.get(spec.run_id)
        if not _ok(row):
            failed.append(
                f"target {study.targets[j]:.3f} m, f_nd {study.forces[i]:g} N: {row.get('error') if row else 'not run'}"
            )
            continue
        assert row is not None
        for key, grid in grids.items():
            value = row.get(key)
            grid[i, j] = value if isinstance(value, (int, float)) else np.nan
    lines = [
        "## 3. Where and how hard to brace",
        "",
        f"Contact `{study.contact}`: brace target along {study.axis} (its start position +- the span) and desired",
        "normal force; the rest as in the scenario. Best cell (least) marked.",
        "",
    ]
    header = ["f_nd [N] \\ target " + study.axis + " [m]", *[f"{t:.3f}" for t in study.targets]]
    for key, title in (("energy_consumed_j", "energy consumed [J]"), ("hand_rms_error_m", "hand RMS error [m]")):
        grid = grids[key]
        lines += [f"**{title}**", "", _table(header, [[f, *grid[i]] for i, f in enumerate(study.forces)]), ""]
        if np.isfinite(grid).any():
            i, j = (int(x) for x in np.unravel_index(np.nanargmin(grid), grid.shape))
            lines += [
                f"- least {title.split(' [')[0]}: {grid[i, j]:.4g} at target {study.axis} = "
                f"{study.targets[j]:.3f} m, f_nd = {study.forces[i]:g} N",
                "",
            ]
    lines += [f"- failed: {f}" for f in failed]
    lines += ["", "![energy and hand error over brace target and force](placement.png)", ""]
    _draw_placement(study, store, grids)
    return lines


def _draw_placement(study: Study, store: ResultsStore, grids: dict[str, np.ndarray]) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 4.0), layout="constrained")
    fig.suptitle(f"{study.scenario}: brace placement and force")
    axes = fig.subplots(1, 2)
    for ax, (key, title) in zip(
        axes, (("energy_consumed_j", "energy consumed [J]"), ("hand_rms_error_m", "hand RMS error [m]")), strict=True
    ):
        grid = grids[key]
        image = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis")
        fig.colorbar(image, ax=ax)
        ax.set_xticks(range(len(study.targets)), [f"{t:.3f}" for t in study.targets])
        ax.set_yticks(range(len(study.forces)), [f"{f:g}" for f in study.forces])
        ax.set(title=title, xlabel=f"brace target {study.axis} [m]", ylabel="desired normal force [N]")
        for i in range(grid.shape[0]):
            for j in range(grid.shape[1]):
                text = f"{grid[i, j]:.3g}" if np.isfinite(grid[i, j]) else "failed"
                ax.text(j, i, text, ha="center", va="center", fontsize=7, color="white")
        if np.isfinite(grid).any():
            i, j = (int(x) for x in np.unravel_index(np.nanargmin(grid), grid.shape))
            ax.plot(j, i, marker="*", markersize=22, markerfacecolor="none", markeredgecolor="red", markeredgewidth=2)
    fig.savefig(store.output / "placement.png", dpi=110)


def _warnings_section(rows: dict[str, dict[str, Any]]) -> list[str]:
    """The runs' warnings (summary.json's), each once with the number of runs that had it."""
    counts = row_warnings(list(rows.values()))
    if not counts:
        return []
    return [
        "## Warnings",
        "",
        *[f"- {text} ({runs} run{'s' if runs > 1 else ''})" for text, runs in counts.items()],
        "",
    ]


def write_report(study: Study, output: Path, wall_time_s: float, executor: str, reused: int = 0) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    store = ResultsStore(output)
    rows = {spec.run_id: row for spec in study.specs if (row := store.row(spec.run_id)) is not None}
    ok = sum(1 for row in rows.values() if _ok(row))
    duration = study.duration if study.duration is not None else study.specs[0].duration
    compute = sum(float(row.get("wall_time_s") or 0.0) for row in rows.values())
    lines = [
        f"# Bracing study: {study.config.name}",
        "",
        f"{len(study.specs)} in-process runs of {duration:g} s (the nodes' simulator and controller cores, "
        f"lockstep); {ok} ok, {len(rows) - ok} failed. {compute:.0f} s of run time in all; this report's "
        f"invocation took {wall_time_s:.0f} s on {executor}{f' ({reused} runs reused)' if reused else ''}. "
        "Every run's row: `results.csv` / `results.parquet`; its summary and arrays: `runs/<run id>/`.",
        "",
        *_bracing_section(study, store, rows),
        *_gains_section(study, store, rows),
        *_placement_section(study, store, rows),
        *_warnings_section(rows),
    ]
    path = output / REPORT
    path.write_text("\n".join(lines))
    return path


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="bracing-study", description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("scenario", help="'paper' or a scenario params file")
    parser.add_argument("--output", required=True, type=Path, help="report directory (resumable)")
    parser.add_argument("--duration", type=float, default=None, help="sim time per run [s] (default: the file's)")
    parser.add_argument("--workers", type=int, default=None, help="local worker processes (default: cores)")
    parser.add_argument("--scheduler", default=None, help="Dask scheduler tcp://HOST:PORT, or 'local'")
    parser.add_argument(
        "--set",
        dest="sets",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scenario parameter in every run",
    )
    parser.add_argument("--positions", type=int, default=5, help="brace targets in the placement grid")
    parser.add_argument("--span", type=float, default=0.15, help="placement targets: start position +- span [m]")
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args(argv)
    if args.duration is not None and args.duration <= 0:
        parser.error("--duration must be > 0")
    if args.positions < 1 or args.span < 0:
        parser.error("--positions must be >= 1 and --span >= 0")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    handle_stop_signals()
    start = time.perf_counter()
    try:
        config = resolve_scenario(args.scenario)
        study = build_study(config, args.duration, parse_single(args.sets), args.positions, args.span)
        ResultsStore(args.output).check_manifest(config)
        executor = make_executor(args.workers, args.scheduler)
    except ConfigError as exc:
        print(f"bracing-study: error: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    try:
        with executor:
            where = executor.description
            print(f"bracing-study: {len(study.specs)} runs of {config} on {where}", file=sys.stderr)
            result = run_sweep(study.specs, args.output, executor, progress=not args.no_progress)
    except KeyboardInterrupt:
        print("bracing-study: interrupted; the same command again runs the rest", file=sys.stderr)
        return EXIT_INTERRUPTED
    report = write_report(study, args.output, time.perf_counter() - start, where, result.skipped)
    print(f"bracing-study: {result.ran} run now, {result.skipped} reused; report: {report}")
    failed = sum(1 for row in result.rows if row.get("status") == STATUS_FAILED)
    if failed or result.lost:
        print(
            f"bracing-study: {failed} run(s) failed, {len(result.lost)} lost: see the report's cells and "
            f"{args.output / 'results.csv'}",
            file=sys.stderr,
        )
    return EXIT_FAILED if result.lost or any_failed(result.rows) else 0


if __name__ == "__main__":
    sys.exit(main())

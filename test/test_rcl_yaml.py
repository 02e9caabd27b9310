"""Scenario files and --set values read once, the way the nodes' rcl reads them.

rcl types YAML 1.1 scalars its own way (a bare y is true, 1e-3 a number) and refuses a list mixing
types, an empty value, an alias; PyYAML did neither, so a scenario ran in process and killed both
nodes. Here: our reading agrees with the real rcl, what rcl would refuse is mended (axis names stay
names, a number list with an int becomes floats) or refused naming the key and the fix, and the same
holds for bracing-pair, in-process runs, sweeps, studies and a node started by hand.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml
from conftest import PAPER_YAML, REPO_ROOT
from ros_helpers import isolated_env, pair_argv, run

from bracing_bringup.run_plan import PARAMS_FILE
from bracing_core import rcl_yaml, schema
from bracing_core.overrides import parse_single, parse_sweep
from bracing_core.params import ConfigError
from bracing_core.rcl_yaml import load_params_file
from bracing_core.rollout import build_scenario
from bracing_experiments.study import build_study
from bracing_experiments.sweep import build_specs

# Read by the real rcl in a node process: {"name": [type, value]} or {"error": text}.
_RCL_READER = """
import json, sys, rclpy
from rclpy.node import Node
try:
    rclpy.init(args=["reader", "--ros-args", "--params-file", sys.argv[1]])
except Exception as exc:
    print(json.dumps({"error": str(exc)})); sys.exit(0)
node = Node("reader", automatically_declare_parameters_from_overrides=False)
out = {n: [p.type_.name, p.value if not isinstance(p.value, (bytes, bytearray)) else None]
       for n, p in node._parameter_overrides.items()}
print(json.dumps({n: [t, list(v) if hasattr(v, "tolist") or isinstance(v, tuple) else v] for n, (t, v) in out.items()}))
node.destroy_node(); rclpy.shutdown()
"""


def rcl_reads(path: Path) -> dict[str, Any]:
    """What the real rcl makes of a params file with a ``reader`` section (a node process of its own)."""
    done = subprocess.run(
        [sys.executable, "-c", _RCL_READER, str(path)], env=isolated_env(), capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    return dict(json.loads(done.stdout.strip().splitlines()[-1]))


def reader_file(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "reader.yaml"
    path.write_text("reader:\n  ros__parameters:\n" + body)
    return path


SCALARS = [
    "y", "n", "Y", "yes", "off", "true", "x", "z", "1e-3", "1E5", "inf", "nan", ".inf", "-.Inf", ".NaN",
    "010", "08", "0x1A", "0x1p3", "1_000", "1:20", "null", "~", "1.", ".5", "+1", "-0", "2001-12-14",
    "0b11", "1e400", "1e-310", "99999999999999999999", "'y'", '"1e-3"', "!!str y", "!!str 1", "!!float 1",
]  # fmt: skip
_TYPES = {bool: "BOOL", int: "INTEGER", float: "DOUBLE", str: "STRING"}
SIM, BOTH = ("bracing_simulator",), ("bracing_simulator", "bracing_controller")


def test_scalars_are_typed_as_the_real_rcl_types_them(tmp_path: Path) -> None:
    body = "".join(f"    p{i}: {text}\n" for i, text in enumerate(SCALARS))
    read = rcl_reads(reader_file(tmp_path, body))
    for i, text in enumerate(SCALARS):
        kind, value = read[f"p{i}"]
        ours = rcl_yaml.read_value("p", text, "test")
        assert isinstance(ours, rcl_yaml.Scalar)
        assert _TYPES[type(ours.value)] == kind, (text, ours.value, kind, value)
        assert ours.value == value or (isinstance(value, float) and math.isnan(value) and math.isnan(ours.value))


@pytest.mark.parametrize(
    ("text", "fix"),
    [
        ("[y, z]", '["y", "z"]'),  # the hand.axes
        ("[0, 2.0, 0.45]", "[0.0, 2.0, 0.45]"),  # the issue's --set hand.trajectory.center
        ("[1.0, y]", "one type"),
    ],
)
def test_a_list_rcl_refuses_is_one_we_name_with_its_fix(tmp_path: Path, text: str, fix: str) -> None:
    assert "Sequence should be of same type" in rcl_reads(reader_file(tmp_path, f"    v: {text}\n"))["error"]
    explained = rcl_yaml.explain(["--ros-args", "--params-file", str(tmp_path / "reader.yaml")])
    assert explained is not None and explained.startswith(f"v: {text}") and fix in explained


def test_what_we_write_the_real_rcl_reads_back_unchanged(tmp_path: Path) -> None:
    params: dict[str, Any] = {
        "axes": ["y", "z"],
        "names": ["n", "null", "1e-3", "010", "true", ""],
        "text": "y",
        "number": 1e-6,
        "big": 1e300,
        "integer": 3,
        "flag": False,
        "floats": [0.0, 2.0, 0.45],
        "empty": [],
        "hand.kp": [300.0, 300.0],
    }
    path = tmp_path / "reader.yaml"
    path.write_text(rcl_yaml.dump({"reader": {"ros__parameters": params}}))
    read = rcl_reads(path)
    assert "error" not in read, read
    for name, value in params.items():
        if value == []:
            assert read[name][0] == "NOT_SET"  # rcl's empty list, which the configuration reads as empty
        else:
            assert read[name][1] == value, name
    assert read["integer"][0] == "INTEGER" and read["number"][0] == "DOUBLE"


def test_every_default_the_reference_shows_pastes_into_yaml(tmp_path: Path) -> None:
    """The parameter reference (docs/reference/parameters.md, schema.default_text) shows values as they
    are written in a scenario file: pasted as is, the real rcl reads each as the parameter's own type."""
    pasted: dict[str, tuple[schema.Param, str]] = {}
    for param in (*schema.SHARED, *schema.SIMULATOR, *schema.CONTROLLER, *schema.CONTACT):
        text = param.default_text()
        if text.startswith(("required", "none")) or "per joint" in text or text == "[]":
            continue  # no value to paste
        pasted[f"p{len(pasted)}"] = (param, text)
    body = "".join(f"    {name}: {text}\n" for name, (_, text) in pasted.items())
    read = rcl_reads(reader_file(tmp_path, body))
    assert "error" not in read, read
    wanted = {
        schema.Kind.DOUBLE: ("DOUBLE", "INTEGER"),  # an integer is a number to the configuration
        schema.Kind.INTEGER: ("INTEGER",),
        schema.Kind.BOOL: ("BOOL",),
        schema.Kind.STRING: ("STRING",),
        schema.Kind.STRING_ARRAY: ("STRING_ARRAY",),
        schema.Kind.DOUBLE_ARRAY: ("DOUBLE_ARRAY",),
    }
    for name, (param, text) in pasted.items():
        assert read[name][0] in wanted[param.kind], (param.name, text, read[name])


# -- the cases, through every reader -------------------------------------------------------
def bare_axes_scenario(tmp_path: Path) -> Path:
    """The paper scenario as a new user writes it: axis names unquoted (the way the reference showed
    them), an integer in a list of decimals, a step in exponent notation."""
    text = PAPER_YAML.read_text()
    text = text.replace('brace_axes: ["y"]', "brace_axes: [y]").replace('plane: ["y", "z"]', "plane: [y, z]")
    text = text.replace('axes: ["y", "z"]', "axes: [y, z]").replace("center: [0.0, 1.1, 0.6]", "center: [0, 1.1, 0.6]")
    text = text.replace("step: 0.001 ", "step: 1e-3  ").replace(
        "urdf: paper_4link.urdf", f"urdf: {PAPER_YAML.parent}/paper_4link.urdf"
    )
    assert text.count("[y, z]") == 3 and "[y]" in text and "[0, 1.1" in text and "1e-3" in text
    path = tmp_path / "bare.yaml"
    path.write_text(text)
    return path


def test_in_process_runs_read_a_scenario_as_the_nodes_do(tmp_path: Path) -> None:
    config = bare_axes_scenario(tmp_path)
    controller = load_params_file(config, "bracing_controller")
    assert controller["hand.axes"] == ["y", "z"] and controller["contacts.elbow.brace_axes"] == ["y"]
    assert controller["hand.trajectory.center"] == [0.0, 1.1, 0.6]
    assert all(isinstance(v, float) for v in controller["hand.trajectory.center"])
    assert load_params_file(config, "bracing_simulator")["step"] == 0.001  # PyYAML read the text "1e-3"
    scenario = build_scenario(config)
    assert scenario.controller is not None and scenario.controller.config.hand_task.axes == (1, 2)  # y, z


def test_set_values_are_read_as_the_nodes_read_them() -> None:
    values = parse_single(["hand.trajectory.center=[0,2.0,0.45]", "hand.axes=[y,z]", "step=1e-3"])
    assert values == {"hand.trajectory.center": [0.0, 2.0, 0.45], "hand.axes": ["y", "z"], "step": 0.001}
    assert all(isinstance(v, float) for v in values["hand.trajectory.center"])
    assert parse_sweep(["hand.axes=[y,z],[z]"]) == {"hand.axes": [["y", "z"], ["z"]]}
    with pytest.raises(ConfigError, match=r"hand\.kp: \[300, y\] mixes .* quote the text|hand\.kp: \[300, y\] mixes"):
        parse_single(["hand.kp=[300, y]"])


def test_sweeps_and_studies_read_the_same(tmp_path: Path) -> None:
    config = bare_axes_scenario(tmp_path)
    (spec,) = build_specs(config, ["hand.trajectory.center=[0,1.1,0.6]"], zipped=False, duration=0.05)
    assert spec.ctl_params["hand.axes"] == ["y", "z"]
    assert spec.ctl_params["hand.trajectory.center"] == [0.0, 1.1, 0.6]
    study = build_study(config, duration=0.05, positions=1)
    assert study.specs and all(s.ctl_params["hand.trajectory.plane"] == ["y", "z"] for s in study.specs)


@pytest.mark.parametrize(
    ("line", "written", "key", "nodes"),
    [
        ("desired_normal_force: 10.0", "desired_normal_force:\n", "desired_normal_force: no value", BOTH),
        ("kp: [100.0]", "kp: [100, y]", r"kp: \[100, y\] mixes integers and true/false", BOTH),
        ("min_subscribers: 1", "min_subscribers: 1\n    use_sim_time: 1", "use_sim_time: expected true", SIM),
    ],
    ids=["empty", "mixed", "use_sim_time"],
)
def test_what_rcl_would_refuse_and_cannot_be_mended_is_named(
    tmp_path: Path, line: str, written: str, key: str, nodes: tuple[str, ...]
) -> None:
    text = PAPER_YAML.read_text()
    assert line in text
    path = tmp_path / "bad.yaml"
    path.write_text(text.replace(line, written, 1))
    for node in nodes:
        with pytest.raises(ConfigError, match=rf"{key}.*(rcl|rclpy)"):
            load_params_file(path, node)


def test_an_alias_is_refused_naming_the_key(tmp_path: Path) -> None:
    path = tmp_path / "alias.yaml"
    path.write_text("/**:\n  ros__parameters:\n    a: &g [1.0]\n    motors:\n      gear_ratio: *g\n")
    with pytest.raises(
        ConfigError, match=r"motors\.gear_ratio: \*g is a YAML alias .*rcl refuses: write the value out"
    ):
        load_params_file(path, "bracing_simulator")


# -- the nodes over DDS ---------------------------------------------------------------------------
def test_pair_runs_a_scenario_with_bare_axis_names(tmp_path: Path) -> None:
    """The issue: the nodes died with "Sequence should be of same type" on hand.axes: [y, z]."""
    output = tmp_path / "run"
    done = run(
        pair_argv(output, "--duration", "0.05", "--no-animation", config=bare_axes_scenario(tmp_path)), timeout=240
    )
    assert done.returncode == 0, done.stdout + done.stderr
    given = yaml.safe_load((output / PARAMS_FILE).read_text())["bracing_controller"]["ros__parameters"]
    assert given["hand.axes"] == ["y", "z"] and given["hand.trajectory.center"] == [0.0, 1.1, 0.6]


def test_pair_runs_a_set_list_mixing_ints_and_floats(tmp_path: Path) -> None:
    output = tmp_path / "run"
    argv = pair_argv(output, "--duration", "0.05", "--no-animation", "--set", "hand.trajectory.center=[0,1.1,0.6]")
    done = run(argv, timeout=240)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "center: [0.0, 1.1, 0.6]" in (output / PARAMS_FILE).read_text()


def test_a_node_started_by_hand_names_what_rcl_refused(tmp_path: Path) -> None:
    bad = tmp_path / "mine.yaml"
    bad.write_text("bracing_controller:\n  ros__parameters:\n    hand:\n      axes: [y, z]\n")
    argv = [sys.executable, "-m", "bracing_controller.node", "--ros-args", "--params-file", str(PAPER_YAML)]
    done = run([*argv, "--params-file", str(bad)], timeout=60)
    assert done.returncode == 2, done.stdout + done.stderr
    assert "hand.axes: [y, z] mixes true/false and text" in done.stderr and 'quote the text, ["y", "z"]' in done.stderr


def test_the_shipped_scenarios_are_read_by_rcl_as_by_us(tmp_path: Path) -> None:
    """Every file in config/ gives the same values to both readers (nothing to mend in them)."""
    for config in sorted((REPO_ROOT / "config").glob("*.yaml")):
        assert rcl_yaml.explain(["--params-file", str(config)]) is None, config.name
        for node in ("bracing_simulator", "bracing_controller"):
            ours = load_params_file(config, node)
            raw = rcl_yaml.node_sections(config, node)
            for name, leaf in raw.items():
                rcl = [item.value for item in leaf] if isinstance(leaf, list) else leaf.value
                assert ours[name] == rcl, (config.name, name)

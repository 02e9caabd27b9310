"""One schema per node (bracing_core.schema): the package layout it sits in, the docs derived
from it, and the parameter services a running node offers (what ``ros2 param`` calls)."""

from __future__ import annotations

import ast
import dataclasses
import functools
import re
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import CONFIG_DIR, PAPER_YAML, node_params
from ros_helpers import isolated_env, node_argv, start

from bracing_core import schema
from bracing_core.config import SimulatorConfig
from bracing_core.controller_config import ControllerConfig
from bracing_core.law import DecoupledController

REPO_ROOT = Path(__file__).resolve().parents[1]
SRC = REPO_ROOT / "src"
sys.path.insert(0, str(REPO_ROOT / "tools"))
import docs_reference  # noqa: E402  (tools/ is no package)
import values_stubs  # noqa: E402

NODE_PACKAGES = ("bracing_sim", "bracing_controller", "bracing_mujoco", "bracing_recorder")


def imported_packages(package: str) -> set[str]:
    """Top-level names every module of ``package`` imports (anywhere in the module, its sub-packages too)."""
    found: set[str] = set()
    for path in (SRC / package / package).rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                found |= {alias.name.split(".")[0] for alias in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                found.add(node.module.split(".")[0])
    return found


def test_the_core_never_imports_ros() -> None:
    ros = {"rclpy", "rcl_interfaces", "rosidl_runtime_py", "bracing_msgs", "bracing_ros", *NODE_PACKAGES}
    assert not imported_packages("bracing_core") & ros
    core = SRC / "bracing_core"
    modules = [".".join(p.relative_to(core).with_suffix("").parts) for p in (core / "bracing_core").rglob("*.py")]
    modules = [m.removesuffix(".__init__") for m in modules]
    code = f"import sys; import {', '.join(modules)}; print(sorted(m for m in sys.modules if m.startswith('rcl')))"
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert loaded.strip() == "[]"


def test_no_node_package_imports_another() -> None:
    assert not imported_packages("bracing_ros") & set(NODE_PACKAGES)
    for package in NODE_PACKAGES:
        assert not imported_packages(package) & (set(NODE_PACKAGES) - {package}), package


def yaml_lines(path: Path) -> dict[str, str]:
    """Dotted key -> its line, for a block-style YAML file (by indentation)."""
    keys: dict[str, str] = {}
    stack: list[tuple[int, str]] = []
    for line in path.read_text().splitlines():
        text = line.split("#")[0].rstrip()
        if not text.strip() or ":" not in text or text.lstrip().startswith("-"):
            continue
        indent = len(text) - len(text.lstrip())
        key = text.strip().split(":")[0].strip()
        while stack and stack[-1][0] >= indent:
            stack.pop()
        stack.append((indent, key))
        keys[".".join(k for _, k in stack)] = line
    return keys


@pytest.mark.parametrize("node", ["simulator", "controller"])
def test_the_scenario_file_comments_every_parameter(node: str) -> None:
    lines = yaml_lines(PAPER_YAML)
    section = {"simulator": "bracing_simulator", "controller": "bracing_controller"}[node]
    missing, uncommented = [], []
    for name in schema.all_names(node, ["elbow"]):
        shared = name.startswith("contacts.") or name in {p.name for p in schema.SHARED}
        key = f"{'/**' if shared else section}.ros__parameters.{name}"
        if key not in lines:
            missing.append(name)
        elif "#" not in lines[key]:
            uncommented.append(name)
    assert not missing, f"not in {PAPER_YAML.name}: {missing}"
    assert not uncommented, f"no comment in {PAPER_YAML.name}: {uncommented}"


def test_the_docs_reference_is_the_schema() -> None:
    page = (REPO_ROOT / "docs" / "reference" / "parameters.md").read_text()
    assert page == docs_reference.parameters_page(), "stale: run tools/docs_reference.py"
    for param in (*schema.SHARED, *schema.SIMULATOR, *schema.CONTROLLER, *schema.CONTACT):
        assert f"`{param.name}`" in page


def test_each_default_is_the_one_the_configuration_uses() -> None:
    """A parameter left out takes the schema's default (written once, in the schema)."""
    params = node_params("bracing_simulator")
    for param in schema.SIMULATOR:
        if param.default is not schema.REQUIRED and not isinstance(param.default, schema.PerJoint):
            params.pop(param.name, None)
    config = SimulatorConfig.from_params(params, [CONFIG_DIR])
    for param in schema.SIMULATOR:
        if param.default is not schema.REQUIRED and not isinstance(param.default, schema.PerJoint):
            # a dotted name is a field of a section's own record (plant_error.mass_scale: config.plant_error.mass_scale)
            assert functools.reduce(getattr, param.name.split("."), config) == schema.typed_default(param), param.name


def conforms(value: Any, param: schema.Param) -> bool:
    """Whether a read value is of its parameter's type (``schema.value_type``: None only where it may be)."""
    if value is None:
        return param.default is schema.ABSENT or param.required_if is not None
    if param.words and isinstance(value, str):
        return value in param.words
    one = {
        schema.Kind.DOUBLE: float,
        schema.Kind.INTEGER: int,
        schema.Kind.BOOL: bool,
        schema.Kind.STRING: str,
        schema.Kind.DOUBLE_ARRAY: float,
        schema.Kind.STRING_ARRAY: str,
    }[param.kind]
    if param.kind in (schema.Kind.DOUBLE_ARRAY, schema.Kind.STRING_ARRAY):
        return isinstance(value, tuple) and all(type(v) is one for v in value)
    return type(value) is one


@pytest.mark.parametrize("node", ["simulator", "controller"])
def test_every_parameter_is_one_typed_field_and_every_field_a_parameter(node: str) -> None:
    """The typed values are derived from the schema (``schema.NODE_VALUES``, ``schema.CONTACT_VALUES``): one
    field per entry, dotted names nested, no field without an entry; each read value of its entry's type."""
    fields = schema.flat_names(schema.NODE_VALUES[node])
    assert sorted(fields) == sorted(p.name for p in schema.node_schema(node)) and len(set(fields)) == len(fields)
    assert sorted(schema.flat_names(schema.CONTACT_VALUES)) == sorted(p.name for p in schema.CONTACT)
    values = schema.read(node, node_params(f"bracing_{node}"))
    assert type(values.params) is schema.NODE_VALUES[node]
    assert values.params.robot.joint_names == ("joint1", "joint2", "joint3", "joint4")
    assert values.contacts["elbow"].trajectory.type == "hold"
    declared = values.flat()
    assert [name for name, _, _ in declared] == schema.all_names(node, ["elbow"])
    wrong = [(name, value) for name, param, value in declared if not conforms(value, param)]
    assert not wrong, f"read values not of their parameter's type: {wrong}"


def test_adding_a_parameter_is_one_entry() -> None:
    """A new entry, dotted or not, is a typed field of the derived class, with nothing else written."""
    added = (
        schema.Param("hand.grip.width", schema.Kind.DOUBLE, 0.05, "a new nested parameter", "m"),
        schema.Param("grip_topic", schema.Kind.STRING, "grip", "a new top-level parameter"),
    )
    entries = (*schema.node_schema("controller"), *added)
    kind = schema.section_class("Extended", entries)
    assert sorted(schema.flat_names(kind)) == sorted(p.name for p in entries)
    grip = kind.sections["hand"].sections["grip"]
    assert [(f.name, f.type) for f in dataclasses.fields(grip)] == [("width", float)]
    params = {**node_params("bracing_controller"), "hand.grip.width": 0.07}
    flat = {name: value for name, _, value in schema.read("controller", node_params("bracing_controller")).flat()}
    flat |= {p.name: schema.read_value(p, p.name, params, flat) for p in added}
    values = schema.build(kind, flat)
    assert values.hand.grip.width == 0.07 and values.grip_topic == "grip"
    assert values.hand.frame == flat["hand.frame"]


def test_the_values_stub_mypy_reads_is_the_schemas() -> None:
    """schema/typed_values.pyi declares every derived class with its fields' types (mypy checks their uses)."""
    assert values_stubs.STUB.read_text() == values_stubs.stub_text(), "stale: run python tools/values_stubs.py"
    stub = values_stubs.STUB.read_text()
    assert "class SharedValuesRobot(Section):\n    urdf: str\n" in stub
    assert "class SimulatorValues(SharedValues):\n    initial_position: tuple[float, ...]\n" in stub
    assert "class ContactValuesForceFeedback(Section):\n    kp: float\n" in stub
    assert stub.count("class SharedValuesRobot(") == 1  # the shared sections once, each node's class deriving
    classes = {kind for root in (*schema.NODE_VALUES.values(), schema.CONTACT_VALUES) for kind in _classes(root)}
    assert stub.count("\nclass ") == len(classes)  # each class once
    derived = sum(len(leaves) + len(groups) for leaves, groups in map(schema.own_fields, classes))
    assert len(re.findall(r"^    \w+: ", stub, re.MULTILINE)) == derived  # each class's own leaves and groups


def _classes(kind: type[schema.Section]) -> set[type[schema.Section]]:
    """``kind``, its base's and its groups' classes, nested ones included."""
    if kind is schema.Section:
        return set()
    return {kind, *_classes(kind.__bases__[0]), *(nested for sub in kind.sections.values() for nested in _classes(sub))}


def test_retune_applies_gains_forces_and_voltage_gain_from_the_next_update() -> None:
    """A retuned controller answers exactly as one built with the new values."""
    old = ControllerConfig.from_params(node_params("bracing_controller"), [CONFIG_DIR])
    changes = {
        "hand.kp": [150.0, 120.0],
        "hand.kd": [30.0, 20.0],
        "contacts.elbow.kp": [50.0],
        "contacts.elbow.desired_normal_force": 4.0,
        "voltage_gain": [2.0, 1.0, 1.0, 0.5],
    }
    new = ControllerConfig.from_params(node_params("bracing_controller", own=changes), [CONFIG_DIR])
    rng = np.random.default_rng(3)
    q, dq = rng.uniform(-1.0, 1.0, 4), rng.uniform(-1.0, 1.0, 4)
    retuned, fresh = DecoupledController(old), DecoupledController(new)
    for controller in (retuned, fresh):
        controller.update(0.0, q, dq)  # targets from the first state
    before = retuned.update(0.1, q, dq).command
    retuned.retune(new)
    after, expected = retuned.update(0.2, q, dq), fresh.update(0.2, q, dq)
    np.testing.assert_array_equal(after.command, expected.command)
    np.testing.assert_array_equal(retuned.desired_normal_force, [4.0])
    assert not np.allclose(before, after.command)


# ------------------------------------------------------------------ over DDS: ros2 param


@pytest.fixture()
def controller_node() -> Iterator[tuple[Any, Any, Any, subprocess.Popen[str]]]:
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter_client import AsyncParameterClient

    env = isolated_env()
    process = start(node_argv("bracing_controller.node"), env)
    context = Context()
    rclpy.init(context=context, domain_id=int(env["ROS_DOMAIN_ID"]))
    node = rclpy.create_node("param_test", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    client = AsyncParameterClient(node, "bracing_controller")
    deadline = time.monotonic() + 30.0
    while not client.services_are_ready() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.1)
    assert client.services_are_ready(), "the controller's parameter services did not appear"
    # Ready means the client has matched the services' request readers, not that they have matched its
    # response reader: a first answer can be lost (seen in CI, a 10 s wait for list_parameters). Ask
    # until one answer comes back; every call after it has its way back.
    while time.monotonic() < deadline:
        answered = client.list_parameters()
        executor.spin_until_future_complete(answered, timeout_sec=1.0)
        if answered.done():
            break
    try:
        yield client, executor, node, process
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        process.terminate()
        process.communicate(timeout=30)


def call(executor: Any, future: Any) -> Any:
    executor.spin_until_future_complete(future, timeout_sec=10.0)
    assert future.done()
    return future.result()


def test_parameter_services_list_describe_get_and_set(controller_node: Any) -> None:
    from rcl_interfaces.msg import ParameterType
    from rclpy.parameter import Parameter

    client, executor, _, process = controller_node
    listed = set(call(executor, client.list_parameters()).result.names)
    assert set(schema.all_names("controller", ["elbow"])) <= listed

    names = ["hand.kp", "damping_lambda", "bracing"]
    described = {d.name: d for d in call(executor, client.describe_parameters(names)).descriptors}
    assert "(per run: taken from the node's next run on)" in described["bracing"].additional_constraints
    assert described["hand.kp"].type == ParameterType.PARAMETER_DOUBLE_ARRAY
    assert "hand task stiffness" in described["hand.kp"].description and "[N/m]" in described["hand.kp"].description
    assert not described["hand.kp"].read_only
    assert described["damping_lambda"].type == ParameterType.PARAMETER_DOUBLE
    assert "needs a fresh start" in described["damping_lambda"].additional_constraints  # refused by the node

    values = call(executor, client.get_parameters(["hand.kp", "input_mode"])).values
    assert list(values[0].double_array_value) == [300.0, 300.0] and values[1].string_value == "voltage"

    accepted = call(executor, client.set_parameters([Parameter("hand.kp", value=[150.0, 150.0])])).results[0]
    assert accepted.successful, accepted.reason
    assert list(call(executor, client.get_parameters(["hand.kp"])).values[0].double_array_value) == [150.0, 150.0]

    wrong = call(executor, client.set_parameters([Parameter("hand.kp", value=[1.0])])).results[0]
    assert not wrong.successful and "hand.kp: expected 2 values" in wrong.reason
    negative = call(executor, client.set_parameters([Parameter("voltage_gain", value=[1.0, -1.0, 1.0, 1.0])]))
    assert not negative.results[0].successful and "voltage_gain" in negative.results[0].reason
    read_only = call(executor, client.set_parameters([Parameter("damping_lambda", value=0.1)])).results[0]
    assert not read_only.successful and read_only.reason.startswith("damping_lambda: cannot change while running")
    assert list(call(executor, client.get_parameters(["hand.kp"])).values[0].double_array_value) == [150.0, 150.0]
    per_run = call(executor, client.set_parameters([Parameter("bracing", value=False)])).results[0]
    assert per_run.successful, per_run.reason

    process.terminate()
    log = process.communicate(timeout=30)[0]
    assert "retuned (from the next update): hand.kp = [150.0, 150.0]" in log
    assert "from the next run: bracing = False" in log


def test_the_shared_and_path_sections_are_one_class_each() -> None:
    """Both nodes' shared sections are one class (their base), as are the hand's and each brace's path; a section
    that gives its base's parameter another type is refused."""
    simulator, controller = schema.NODE_VALUES["simulator"], schema.NODE_VALUES["controller"]
    assert simulator.__bases__ == controller.__bases__ == (schema.SHARED_VALUES,)
    assert simulator.sections["robot"] is controller.sections["robot"] is schema.SHARED_VALUES.sections["robot"]
    hand_path = controller.sections["hand"].sections["trajectory"]
    brace_path = schema.CONTACT_VALUES.sections["trajectory"]
    assert hand_path.__bases__ == brace_path.__bases__ == (schema.TRAJECTORY_VALUES,)
    assert schema.own_fields(hand_path) == (["point"], []) and schema.own_fields(brace_path) == ([], [])
    assert (hand_path.params["type"].default, brace_path.params["type"].default) == ("circle", "hold")
    retyped = schema.Param("period", schema.Kind.STRING, "slow", "a path's period, as a word")
    with pytest.raises(ValueError, match="period already a field of TrajectoryValues"):
        schema.section_class("Odd", [retyped], schema.TRAJECTORY_VALUES)


@pytest.mark.parametrize("section", ["sensors", "plant_error"])
def test_exact_sensing_and_no_plant_error_are_the_schema_defaults(section: str) -> None:
    """sensors.exact and plant_error.none hold at the schema's defaults (the seed alone keeps the sensors exact) and
    not once any other of their parameters differs from its default."""
    config = SimulatorConfig.from_params(node_params("bracing_simulator"), [CONFIG_DIR])
    values = getattr(config, section)
    at_default = values.exact if section == "sensors" else values.none
    assert at_default
    for field, param in values.params.items():
        changed = dataclasses.replace(values, **{field: "other.urdf" if field == "urdf" else param.default + 1})
        still = changed.exact if section == "sensors" else changed.none
        assert still is (field == "noise_seed"), field

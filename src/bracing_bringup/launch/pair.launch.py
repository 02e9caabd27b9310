"""The simulator, the controller and the recorder from one launch file, for a system ROS 2 Jazzy:

    ros2 launch bracing_bringup pair.launch.py config:=config/paper_4link.yaml output:=out/launched
        [duration:=10.0] [set:="hand.kp=[300,300] contacts.elbow.desired_normal_force=5"]

The same run as ``bracing-pair`` (its parameters and processes: ``bracing_bringup.run_plan.plan_run``),
in the domain the shell has (``ROS_DOMAIN_ID``). The recorder closes the bag once it has every
state, and the launch ends with it; ``bracing-report OUTPUT/bag`` draws the figures afterwards.
bracing-pair remains the way to run without a launch installation (none exists on the package
index): it also picks a free domain, supervises, reports and cleans up after a failed start.
"""

from __future__ import annotations

import shlex
import signal

from launch import LaunchContext, LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, OpaqueFunction, RegisterEventHandler
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown, matches_action
from launch.events.process import SignalProcess
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from bracing_bringup.pair import parse_args
from bracing_bringup.run_plan import PARAMS_FILE, plan_run, write_params
from bracing_core.overrides import SIMULATOR


def launch_setup(context: LaunchContext) -> list[object]:
    def arg(name: str) -> str:
        return LaunchConfiguration(name).perform(context)

    # bracing-pair's own command line: the same run, the same parameters.
    argv = ["--config", arg("config"), "--output", arg("output")]
    argv += ["--duration", arg("duration")] if arg("duration") else []
    for assignment in shlex.split(arg("set")):
        argv += ["--set", assignment]
    options = parse_args(argv)
    if (options.output / "bag").exists():
        raise ValueError(f"output: {options.output / 'bag'} exists already; choose a new output directory")
    plan = plan_run(options)
    # No bracing-pair here to follow run_status: the recorder is its one subscriber (it keeps the warnings).
    plan.node_params[SIMULATOR]["min_status_subscribers"] = 1
    options.output.mkdir(parents=True, exist_ok=True)
    write_params(options.output / PARAMS_FILE, plan.node_params)
    nodes = {
        process.name: Node(
            package=process.package,
            executable=process.executable,
            arguments=list(process.arguments),
            ros_arguments=list(process.ros_arguments),
            output="screen",
        )
        for process in plan.processes(options.output)
    }
    controller_done = SignalProcess(signal_number=signal.SIGINT, process_matcher=matches_action(nodes["controller"]))
    return [
        *nodes.values(),
        # The simulator ends by itself at its duration: then the controller (its answers all out),
        RegisterEventHandler(
            OnProcessExit(target_action=nodes["simulator"], on_exit=[EmitEvent(event=controller_done)])
        ),
        # and the launch once the recorder has closed the bag.
        RegisterEventHandler(
            OnProcessExit(target_action=nodes["recorder"], on_exit=[EmitEvent(event=Shutdown(reason="bag closed"))])
        ),
    ]


def generate_launch_description() -> LaunchDescription:
    return LaunchDescription(
        [
            DeclareLaunchArgument("config", description="scenario params file (config/paper_4link.yaml)"),
            DeclareLaunchArgument("output", description="run directory: params.yaml and the bag (OUTPUT/bag)"),
            DeclareLaunchArgument("duration", default_value="", description="sim time [s] (default: the file's)"),
            DeclareLaunchArgument("set", default_value="", description="KEY=VALUE overrides, as bracing-pair --set"),
            OpaqueFunction(function=launch_setup),
        ]
    )

from glob import glob

from setuptools import find_packages, setup

package_name = "bracing_bringup"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/launch", ["launch/pair.launch.py"]),
        ("share/" + package_name + "/config", sorted(glob("../../config/*.yaml") + glob("../../config/*.urdf"))),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="Bracing maintainers",
    maintainer_email="maintainers@bracing-robotics.org",
    description="Runs the simulator and controller as a pair and records a rosbag2 bag (bracing-pair, the recorder, "
    "launch/pair.launch.py), shows it live (bracing-view), and make run's paper runs; the scenario files.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "pair=bracing_bringup.pair:main",
            "recorder=bracing_bringup.recorder:main",
            "bracing-recorder=bracing_bringup.recorder:main",
            "bracing-pair=bracing_bringup.pair:main",
            "bracing-mujoco-robot=bracing_bringup.mujoco_robot:main",
            "view=bracing_bringup.view:main",
            "bracing-view=bracing_bringup.view:main",
        ],
    },
)

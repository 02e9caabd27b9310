from setuptools import find_packages, setup

package_name = "bracing_mujoco"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="Bracing maintainers",
    maintainer_email="maintainers@bracing-robotics.org",
    description="bracing-mujoco-robot: the scenario's robot in MuJoCo behind a mujoco_ros2_control robot's topics "
    "(bracing-pair --engine mujoco).",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "bracing-mujoco-robot=bracing_mujoco.mujoco_robot:main",
        ],
    },
)

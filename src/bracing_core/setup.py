from setuptools import find_packages, setup

package_name = "bracing_core"

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
    description="The bracing manipulator's numerics without ROS: robot model, motors, contacts, constrained "
    "dynamics, integrator, control law, trajectories, parameter schemas and validation.",
    license="Apache-2.0",
)

from setuptools import find_packages, setup

package_name = "bracing_sim"

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
    description="Constrained multibody + DC-motor simulator of a bracing manipulator (pinocchio), and its ROS 2 node.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "simulator=bracing_sim.node:main",
            "bracing-simulator=bracing_sim.node:main",
        ],
    },
)

from setuptools import find_packages, setup

package_name = "bracing_controller"

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
    description="Decoupled force/position controller of a bracing manipulator (paper eq. 38-41), and its ROS 2 node.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "controller=bracing_controller.node:main",
            "bracing-controller=bracing_controller.node:main",
        ],
    },
)

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
    description="Starts and supervises a run: the simulator, the controller and the recorder as a pair (bracing-pair, "
    "launch/pair.launch.py), the viewer beside them, and make run's paper runs; the scenario files.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "pair=bracing_bringup.pair:main",
            "bracing-pair=bracing_bringup.pair:main",
        ],
    },
)

from setuptools import find_packages, setup

package_name = "bracing_recorder"

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
    description="The recorder: every topic of a run written to a rosbag2 bag (mcap), with the /tf and markers it "
    "derives (bracing-recorder); the recorded topics.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "recorder=bracing_recorder.command:main",
            "bracing-recorder=bracing_recorder.command:main",
        ],
    },
)

from setuptools import find_packages, setup

package_name = "bracing_ros"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["fastdds_profile.xml", "fastdds_profile_network.xml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="Bracing maintainers",
    maintainer_email="maintainers@bracing-robotics.org",
    description="The ROS 2 glue the bracing nodes share: QoS, waits, the node runner, message bytes.",
    license="Apache-2.0",
)

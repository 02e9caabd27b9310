from setuptools import find_packages, setup

package_name = "bracing_analysis"

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
    description="A recorded bracing run read and shown, without ROS: the bag's time series, summary.json, "
    "the paper's figures, the animation and side-by-side comparisons (bracing-report).",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "report=bracing_analysis.report:main",
            "bracing-report=bracing_analysis.report:main",
        ],
    },
)

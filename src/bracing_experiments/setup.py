from setuptools import find_packages, setup

package_name = "bracing_experiments"

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
    description="Many in-process bracing runs, without ROS: sweeps, the paper's studies and the optimiser, "
    "on local worker processes or a Dask cluster (bracing-sweep, bracing-study, bracing-optimize).",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "sweep=bracing_experiments.sweep:main",
            "bracing-sweep=bracing_experiments.sweep:main",
            "study=bracing_experiments.study:main",
            "bracing-study=bracing_experiments.study:main",
            "optimize=bracing_experiments.optimize:main",
            "bracing-optimize=bracing_experiments.optimize:main",
        ],
    },
)

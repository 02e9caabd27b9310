from setuptools import find_packages, setup

package_name = "bracing_view"

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
    description="bracing-view: a run live or from its bag in rerun's web viewer, served on localhost.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "view=bracing_view.view:main",
            "bracing-view=bracing_view.view:main",
        ],
    },
)

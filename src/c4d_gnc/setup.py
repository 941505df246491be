from glob import glob

from setuptools import find_packages, setup

package_name = "c4d_gnc"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*.yaml")),

    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="c4d maintainers",
    maintainer_email="maintainers@c4d.dev",
    description="c4d GNC core: cyclic executive + cascaded multirotor controller",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "core = c4d_gnc.core_node:main",
            "perception = c4d_gnc.perception_node:main",
            "navigation = c4d_gnc.navigation_node:main",
        ],
        "c4d.components": [  # composable (c4d_ros.component); core runs alone: its own real-time loop
            "perception = c4d_gnc.perception_node:component",
            "navigation = c4d_gnc.navigation_node:component",
        ],
    },
)

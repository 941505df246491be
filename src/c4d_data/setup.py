from setuptools import find_packages, setup

package_name = "c4d_data"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", ["config/recorder.yaml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="c4d maintainers",
    maintainer_email="maintainers@c4d.dev",
    description="c4d flight recorder (rosbag2 MCAP), replay, repair and flight analysis reports",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "recorder = c4d_data.recorder_node:main",
            "replay = c4d_data.replay_node:main",
            "analyze = c4d_data.cli:analyze_main",
            "c4d-analyze = c4d_data.cli:analyze_main",
            "repair = c4d_data.cli:repair_main",
            "info = c4d_data.cli:info_main",
            "catalog = c4d_data.cli:catalog_main",
        ],
        "c4d.components": ["recorder = c4d_data.recorder_node:component"],
    },
)

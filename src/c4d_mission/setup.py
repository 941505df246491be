from setuptools import find_packages, setup

package_name = "c4d_mission"

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
    maintainer="c4d maintainers",
    maintainer_email="maintainers@c4d.dev",
    description="c4d mission management: plans, validation, command executor, waypoint guidance",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "mission = c4d_mission.mission_node:main",
            "payload = c4d_mission.payload_node:main",
        ],
        "c4d.components": [
            "mission = c4d_mission.mission_node:component",
            "payload = c4d_mission.payload_node:component",
        ],
    },
)

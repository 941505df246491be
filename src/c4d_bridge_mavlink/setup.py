from setuptools import find_packages, setup

package_name = "c4d_bridge_mavlink"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", ["config/bridge.yaml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="c4d maintainers",
    maintainer_email="maintainers@c4d.dev",
    description="c4d MAVLink 2 ground-station bridge with GCD+-scheduled telemetry",
    license="Apache-2.0",
    entry_points={"console_scripts": ["bridge = c4d_bridge_mavlink.bridge_node:main"],
                  "c4d.components": ["bridge = c4d_bridge_mavlink.bridge_node:component"]},
)

from setuptools import find_packages, setup

package_name = "c4d_sched"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", ["config/paparazzi_telemetry.yaml", "config/worked_example.yaml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="c4d maintainers",
    maintainer_email="maintainers@c4d.dev",
    description="GCD+ offset assignment, baselines, exact FIFO evaluator and c4d-sched CLI",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "c4d-sched = c4d_sched.cli:main",
        ],
    },
)

from glob import glob

from setuptools import find_packages, setup

package_name = "c4d_bringup"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*.yaml")),
        ("share/" + package_name + "/launch", glob("launch/*.launch.py")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="c4d maintainers",
    maintainer_email="maintainers@c4d.dev",
    description="c4d bring-up: the c4d CLI (up, fly, status) and launch files",
    license="Apache-2.0",
    entry_points={"console_scripts": ["c4d = c4d_bringup.cli:main", "container = c4d_bringup.container:main"]},
)

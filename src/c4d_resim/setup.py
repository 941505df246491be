from setuptools import find_packages, setup

package_name = "c4d_resim"

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
    description="c4d re-simulation: the GNC libraries re-run over a recorded flight's inputs, with a diff report",
    license="Apache-2.0",
    entry_points={"console_scripts": ["resim = c4d_resim.cli:main"]},
)

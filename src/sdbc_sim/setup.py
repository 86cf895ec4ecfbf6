from setuptools import find_packages, setup

package_name = "sdbc_sim"

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
    maintainer="sdbc team",
    maintainer_email="sdbc@example.org",
    description=(
        "Batched pymunk simulation of robot teams: the gate escape, resource "
        "sharing and predator-prey tasks, and the simulator and controller nodes."
    ),
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "simulator_node = sdbc_sim.nodes.simulator_node:main",
            "controller_node = sdbc_sim.nodes.controller_node:main",
        ],
    },
)

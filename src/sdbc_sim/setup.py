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
    python_requires=">=3.10",
    # What the engine, the tasks and the task-state formalism import. The ROS
    # nodes' rclpy and sdbc_msgs come from ROS 2 (scripts/sdbc setup), not from
    # pip: their console scripts say so when they are missing. Floors: the
    # oldest releases the library's tests were run with and passed, all at once
    # (pydantic 2.7 fails them: it does not resolve the settings' forward
    # references).
    install_requires=[
        "numpy>=2.0",
        "pymunk>=7.0",
        "numba>=0.60",
        "pydantic>=2.8",
        "pyyaml>=6.0.1",
        "matplotlib>=3.9",
    ],
    zip_safe=True,
    maintainer="sdbc team",
    maintainer_email="sdbc@example.org",
    description=(
        "Batched pymunk simulation of robot teams: the paper's gate escape, "
        "resource sharing and predator-prey tasks, aggregation and foraging, and "
        "the simulator and controller nodes."
    ),
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "simulator_node = sdbc_sim.nodes.entry:simulator_node",
            "controller_node = sdbc_sim.nodes.entry:controller_node",
        ],
    },
)

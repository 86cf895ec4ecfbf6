from glob import glob

from setuptools import find_packages, setup

package_name = "sdbc_evolution"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        # ros2 launch finds launch files and their graph files here.
        ("share/" + package_name + "/launch", sorted(glob("launch/*.launch.*"))),
        ("share/" + package_name + "/config", sorted(glob("../../configs/ros/*.yaml"))),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="sdbc team",
    maintainer_email="sdbc@example.org",
    description=(
        "Systematically derived behaviour characterisations (SDBC), novelty "
        "search, the GA and its experiments, and the evolution node."
    ),
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "characteriser_node = sdbc_evolution.nodes.characteriser_node:main",
            "evolution_node = sdbc_evolution.nodes.evolution_node:main",
            "recorder = sdbc_evolution.nodes.recorder_node:main",
            "sdbc-graph = sdbc_evolution.graph.launch:main",
            "sdbc-evolve = sdbc_evolution.run.cli:main",
            "sdbc-study = sdbc_evolution.study.cli:main",
            "sdbc-conformance = sdbc_evolution.conformance:main",
        ],
    },
)

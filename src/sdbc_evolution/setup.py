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
    python_requires=">=3.10",
    # The method, the GA, sdbc-evolve, sdbc-study and sdbc-conformance. The ROS
    # nodes and the live graph need rclpy and sdbc_msgs from ROS 2 (scripts/sdbc
    # setup); their console scripts say so when they are missing. Floors: as
    # sdbc_sim's, the oldest releases the tests passed with.
    install_requires=[
        "sdbc_sim",
        "numpy>=2.0",
        "scipy>=1.13",
        "scikit-learn>=1.4.2",
        "threadpoolctl>=3.1",
        "pydantic>=2.8",
        "pyyaml>=6.0.1",
        "tqdm>=4.60",
        "minisom>=2.3",
        "matplotlib>=3.9",
    ],
    # Imported only by the part that needs them.
    extras_require={
        # DaskEvaluator (sdbc-evolve --scheduler, sdbc-study --scheduler).
        "dask": ["dask[distributed]>=2024.1"],
        # The dcor relevance measure (treatments naming relevance: dcor).
        "dcor": ["dcor>=0.6"],
        # Bags written by the recorder node (which also needs ROS 2).
        "bags": ["rosbags>=0.10"],
    },
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
            "characteriser_node = sdbc_evolution.nodes.entry:characteriser_node",
            "evolution_node = sdbc_evolution.nodes.entry:evolution_node",
            "recorder = sdbc_evolution.nodes.entry:recorder",
            "sdbc-graph = sdbc_evolution.nodes.entry:graph",
            "sdbc-evolve = sdbc_evolution.run.cli:main",
            "sdbc-study = sdbc_evolution.study.cli:main",
            "sdbc-conformance = sdbc_evolution.conformance:main",
        ],
    },
)

"""Installs tolerance_ros with pip (no ROS needed) or with colcon in a ROS 2 workspace (ament_python)."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = "tolerance_ros"


def share(subdir, pattern):
    files = sorted(f for f in glob(f"{subdir}/{pattern}"))
    return (f"share/{PACKAGE}/{subdir}", files) if files else None


data_files = [
    ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
    (f"share/{PACKAGE}", ["package.xml"]),
]
for subdir, pattern in (("config", "*.yaml"), ("config", "*.rviz"), ("config/robots", "*.*"), ("config/budgets", "*.*"),
                        ("config/campaigns", "*.*"), ("config/data", "*.*"), ("config/security", "*.xml"), ("launch", "*.py"),
                        ("schemas", "*.json")):
    entry = share(subdir, pattern)
    if entry:
        data_files.append(entry)

# The shipped configs and schemas, also package data: tolerance_ros/config and tolerance_ros/schemas once installed
# (core/resources.py finds them with importlib.resources; in a source checkout they sit beside the package).
PACKAGE_DATA = {f"{PACKAGE}.config": ["*.yaml", "*.rviz", "robots/*.*", "budgets/*.*", "campaigns/*.*", "data/*.*",
                                      "security/*.xml"],
                f"{PACKAGE}.schemas": ["*.json"]}

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(include=[PACKAGE, f"{PACKAGE}.*"]) + list(PACKAGE_DATA),
    package_dir={f"{PACKAGE}.config": "config", f"{PACKAGE}.schemas": "schemas"},
    package_data=PACKAGE_DATA,
    data_files=data_files,
    python_requires=">=3.10",
    # the floors: .ci/floors.txt, installed and tested by .ci/run on Python 3.12 (test/test_floors.py)
    install_requires=["numpy>=1.26.0", "scipy>=1.11.2", "PyYAML>=6.0.1", "matplotlib>=3.7.3", "pin>=2.7.0",
                      "rosbags>=0.10.10", "orjson>=3.10.0", "threadpoolctl>=3.1.0", "numba>=0.59.0",
                      "llvmlite>=0.42.0", "pybase64>=1.3.1", "cryptography>=3.1"],
    extras_require={"test": ["pytest>=7.0.1", "pytest-xdist>=3.0.2", "hypothesis>=6.11.0", "jsonschema>=4.0.1",
                             "example-robot-data>=4.0.5", "pooch>=1.7.0"],
                    "data": ["pooch>=1.7.0"]},   # tolerance-ros data fetch: the public measurement sets
    zip_safe=False,
    maintainer="tolerance_ros maintainers",
    maintainer_email="maintainers@tolerance-ros.dev",
    description="Kinematic error models, precision analysis and tolerance allocation for robot arms, with ROS 2 nodes",
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [
            "tolerance-ros = tolerance_ros.cli:entry",
            "joint_state_source = tolerance_ros.nodes.joint_state_source:main",
            "error_model_server = tolerance_ros.nodes.error_model_server:main",
            "tolerance_allocator = tolerance_ros.nodes.tolerance_allocator:main",
            "accuracy_monitor = tolerance_ros.nodes.accuracy_monitor:main",
            "simulated_tracker = tolerance_ros.nodes.simulated_tracker:main",
            "trajectory_compensator = tolerance_ros.nodes.trajectory_compensator:main",
        ],
    },
)

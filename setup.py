"""ament_python package gait_biofeedback (builds with colcon or pip)."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "gait_biofeedback"
NODES = {
    "imu_driver": "gait_biofeedback.nodes.imu_driver:main",
    "imu_replayer": "gait_biofeedback.nodes.imu_replayer:main",
    "recorder": "gait_biofeedback.nodes.recorder:main",
    "orientation_filter": "gait_biofeedback.nodes.orientation_filter:main",
    "activity_monitor": "gait_biofeedback.nodes.activity_monitor:main",
    "gait_events": "gait_biofeedback.nodes.gait_events:main",
    "calibration": "gait_biofeedback.nodes.calibration:main",
    "joint_angles": "gait_biofeedback.nodes.joint_angles:main",
    "biofeedback": "gait_biofeedback.nodes.biofeedback:main",
    "foxglove": "gait_biofeedback.nodes.foxglove_view:main",
}

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(include=[PACKAGE, f"{PACKAGE}.*"]),
    package_data={PACKAGE: ["dashboard/*.html", "dashboard/*.js", "dashboard/*.css"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
    ],
    install_requires=["setuptools"],
    zip_safe=False,
    maintainer="gait_biofeedback developers",
    maintainer_email="dev@gait-biofeedback.local",
    description="Wearable-IMU gait biofeedback for stroke rehabilitation: ROS 2 node graph.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [f"{name} = {target}" for name, target in NODES.items()]
        + ["gait-biofeedback = gait_biofeedback.cli:main"],
    },
)

"""gait_biofeedback: wearable-IMU gait biofeedback for stroke rehabilitation (ROS 2 Jazzy)."""

__version__ = "0.1.0"

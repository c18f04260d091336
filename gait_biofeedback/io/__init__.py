"""Recording I/O: rosbag2/MCAP bags (:mod:`gait_biofeedback.io.bag`) and file importers.

Kept import-free so that importing one submodule does not load rclpy for the others.
"""

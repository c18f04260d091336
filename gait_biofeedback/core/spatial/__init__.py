"""Foot trajectories and spatial gait parameters (Suh 2014; gait.md §4): zero-velocity detection, the
zero-velocity-aided error-state Kalman filter, its smoothers (Suh's quadratic program and RTS), and
per-stride stride length, speed, clearance and foot angles."""

"""Trunk activity from one chest accelerometer (thesis ch. 7; gait.md §3): posture, transitions,
walking modality, steps, and the live stream around the monitor."""

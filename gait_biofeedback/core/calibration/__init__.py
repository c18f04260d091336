"""Sensor-to-segment calibration (thesis ch. 3; gait.md §1): the method, where the protocol happened in
a recording, and the live buffer a Calibrate request looks back over."""

"""The ROS-free core, grouped by pipeline step: orientation, calibration, joints, gait, activity,
biofeedback. Each step has a streaming class (``update(sample) -> result``, samples stamped in int ns),
a batch function (exported by :mod:`gait_biofeedback.batch`) and its parameters' dataclass.

Docstrings cite the thesis as ``[T Eq n]`` / ``thesis §x.y`` and the method digests as
``gait.md §n`` / ``orientation.md §n``: ``docs/spec/`` of the repository; frames, quaternion order,
units and time are ``docs/conventions.md``.
"""

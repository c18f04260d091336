"""The wire: every topic, message type and QoS (:mod:`~gait_biofeedback.wire.topics`), stamps, and one
module per message family converting between ROS messages and the core, both ways, with its enum
tables. Nodes, ``analyze``, ``report`` and the simulator's recordings import it; nothing in the core
does (``docs/conventions.md``)."""

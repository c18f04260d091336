"""Gain optimisation of the orientation filters (thesis §4.2.3, §5.2.3): particle swarm optimisation per
sensor location on recordings with reference orientations, cross-validated by group.

Modules: :mod:`.pso` (the optimiser), :mod:`.space` (decision variables of thesis Table 5),
:mod:`.data` (recordings with references: BROAD, simulated subjects), :mod:`.run` (cross-validation,
the thesis-style table, ``config/orientation_filters.yaml``). Entry point: ``gait-biofeedback tune``.
"""

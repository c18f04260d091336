"""The patient's body dimensions: one declaration for every stage that needs them.

The activity monitor scales its sit/stand height gate by the thigh length (thesis §7.2.5), the
joint-angle node draws the ``skeleton`` and the dashboard the stick figure from the same lengths. In a
params file they go under ``/**:`` (every node) so that one value serves them all. Defaults: an adult
of about 1.75 m (thigh 0.42 m greater trochanter to knee, the activity monitor's reference).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from gait_biofeedback.core.params import param, same_as


@dataclass(frozen=True)
class BodyDimensions:
    """Segment lengths (m) of the patient."""

    thigh_length_m: float = param(0.42, "thigh length, hip joint to knee joint", "m", low=0.2, high=0.7)
    shank_length_m: float = param(0.43, "shank length, knee joint to ankle joint", "m", low=0.2, high=0.7)
    hip_width_m: float = param(0.18, "distance between the hip joint centres", "m", low=0.1, high=0.5)
    foot_length_m: float = param(0.14, "ankle joint to the toes, along the foot", "m", low=0.05, high=0.35)
    ankle_height_m: float = param(0.08, "ankle joint above the sole", "m", low=0.02, high=0.2)
    trunk_length_m: float = param(0.45, "pelvis origin to the shoulders (stick figure only)", "m",
                                  low=0.2, high=0.9)


@dataclass(frozen=True)
class StickFigureDimensions:
    """The body dimensions a stick figure of the legs is drawn with: the parameters of every stage
    that draws one (the ``skeleton`` markers, the dashboard)."""

    thigh_length_m: float = same_as(BodyDimensions, "thigh_length_m")
    shank_length_m: float = same_as(BodyDimensions, "shank_length_m")
    hip_width_m: float = same_as(BodyDimensions, "hip_width_m")
    foot_length_m: float = same_as(BodyDimensions, "foot_length_m")
    ankle_height_m: float = same_as(BodyDimensions, "ankle_height_m")

    @property
    def body(self) -> BodyDimensions:
        """These dimensions as :class:`BodyDimensions` (the others at their defaults)."""
        names = (f.name for f in dataclasses.fields(StickFigureDimensions))
        return BodyDimensions(**{name: getattr(self, name) for name in names})

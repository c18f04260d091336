"""Biofeedback (thesis ch. 8; gait.md §5): the therapist's targets, the per-stride comparison and its
cues, and the normative reference curves."""

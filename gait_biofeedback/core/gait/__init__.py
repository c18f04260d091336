"""Gait events and strides (thesis ch. 6; gait.md §2): Algorithm 1, the angular-velocity comparator,
per-stride temporal parameters, event matching, and the live stream of both feet."""

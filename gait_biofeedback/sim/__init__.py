"""The simulator: synthetic gait sessions with exact ground truth (its own joint definitions, not the
code it tests), and their recordings."""

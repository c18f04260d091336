"""Orientation of each IMU (thesis ch. 2, 4-5; orientation.md): the filters, their gain regulation,
and the stream that gives a filter what a real sample stream needs (stamps, start-up, bad input)."""

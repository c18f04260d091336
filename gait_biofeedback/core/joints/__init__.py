"""Joint angles (gait.md §1.8-1.9): the ISB joint coordinate system, standing offset removal, the live
stream that synchronises segments by stamp, and the stick figure."""

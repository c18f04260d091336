"""ROS-free numerical core: numpy/scipy only, one module per method."""

"""imu_driver's core: the sensors' wire format, device time → ROS time, sequence accounting."""

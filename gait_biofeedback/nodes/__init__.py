"""Thin rclpy nodes: messages <-> core objects, parameters, diagnostics."""

"""ROS 2 (rclpy) adapters: thin nodes over the ROS-free core. The only place that imports rclpy."""

"""ROS 2 (rclpy) adapters: thin nodes over the ROS-free ``services`` and ``core``; the only place that
imports rclpy. Importing this package first caps the numerical libraries' threads (before numpy loads),
so that a solve never stalls a loaded robot computer (see ``core/threads.py``)."""
from ..core.threads import cap_environment

cap_environment()

"""ROS-free core (SI units): geometry, mechanism models, error bounds, analysis, synthesis, accuracy
evaluation, budgets, campaigns and the ingestion of joint states and measured poses."""

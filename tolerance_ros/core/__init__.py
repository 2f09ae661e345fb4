"""ROS-free core: mechanism models, error bounds, analysis, synthesis and accuracy evaluation (SI units)."""

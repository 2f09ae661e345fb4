"""What the ROS nodes run, without ROS: the JSON services' contracts and logic (error model,
allocation), the accuracy monitor, the joint-state sequence and the simulated tracker. Plain values or
duck-typed messages in, plain dicts out."""

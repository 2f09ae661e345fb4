"""Robot programs in their controllers' own formats, corrected through a calibration (ROS-free, SI inside).

``text`` (bytes kept, comments masked, numbers found and written with the digits they need), ``model`` (what the
formats share: targets, their fields and uses), one module per format (``rapid``: ABB RAPID; ``krl``: KUKA KRL;
``fanuc``: FANUC TP ``.ls``; ``urscript``: Universal Robots), ``orientation`` (quaternions, Euler angles and rotation
vectors, written nearest their old values), ``configuration`` (an arm's configuration signs and the nominal inverse
kinematics in a configuration), ``correct`` (all targets at once through ``compensate``, inside the envelope),
``filtering`` (a program read, corrected and written), ``ur_kinematics`` (a calibrated UR arm for its ROS 2 driver).
"""

"""`tolerance-ros ur-kinematics`: a calibration of a Universal Robots arm as the ``kinematics_params`` file its ROS 2
description and driver read (docs/programs.md)."""
from __future__ import annotations

from pathlib import Path

from .common import CLIError, load_model

NAME = "ur-kinematics"
HELP = "write a UR arm's calibration as the kinematics_params YAML of Universal Robots' ROS 2 description and driver"
ROBOT = True


def add_arguments(p):
    p.add_argument("--calibration", required=True, help="calibration.yaml written by calibrate")
    p.add_argument("--out", required=True, metavar="FILE",
                   help="the kinematics file to write (e.g. my_robot_calibration.yaml)")


def run(args):
    from ..core.calibration.calibration_file import load_calibration
    from ..core.models.base import ModelError
    from ..core.programs import ur_kinematics as uk
    model = load_model(args)
    cal = load_calibration(args.calibration, model)
    sha = cal.content_sha256 or ""
    hash_text = f"calib_{int(sha[:16], 16)}" if sha else "calib_0"
    try:
        result = uk.kinematics(model, cal.calibrated_chain(model), hash_text)
    except ModelError as exc:
        raise CLIError(f"--robot: {exc}") from None
    header = [f"Kinematics of {model.name} calibrated by tolerance-ros ({Path(args.calibration).name}, sha256 {sha})",
              "for Universal Robots' ROS 2 description and driver: kinematics_params:=<this file>",
              "angles: the URDF's roll, pitch, yaw (R = Rz(yaw) Ry(pitch) Rx(roll)); lengths m",
              "hash: of this calibration, not of the controller's (the driver says they differ: they do)"]
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(uk.text(result, header))
    lengths = dict(zip(("d1", "a2", "a3", "d4", "d5", "d6"), map(float, result["lengths"])))
    if args.json:
        return {"robot": model.name, "calibration": str(args.calibration), "out": str(out),
                "kinematics": result["kinematics"], "nominal_dh_m": lengths, "controller_base_in_model": result["base"],
                "reproduction_error": result["error"]}
    print(f"robot {model.name}: UR arm of d1 {lengths['d1']:.6g}, a2 {lengths['a2']:.6g}, a3 {lengths['a3']:.6g}, "
          f"d4 {lengths['d4']:.6g}, d5 {lengths['d5']:.6g}, d6 {lengths['d6']:.6g} m; the file reproduces the "
          f"calibrated robot to {result['error']:.1e} m")
    print(f"wrote {out}")

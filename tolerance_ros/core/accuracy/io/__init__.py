"""Measurements in and out, one module per format behind ``read_measurements``: the documented CSV
(``csv_format``), the accuracy monitor's campaign log (``campaign_log``), rosbag2 recordings (``rosbag``).
Every reader returns ``Measurements`` (SI) and raises ``MeasurementError`` naming the file, line and field.
"""
from __future__ import annotations

from pathlib import Path

from .campaign_log import MAX_DEPTH, read_log
from .csv_format import read_csv, write_csv
from .measurements import MeasurementError, Measurements, concat
from .rosbag import is_recording, read_rosbag, write_rosbag
from .text import MAX_LINE

__all__ = ["MAX_DEPTH", "MAX_LINE", "MeasurementError", "Measurements", "concat", "read_csv", "read_log",
           "read_measurements", "read_rosbag", "write_csv", "write_rosbag"]


def read_measurements(path, joint_names=None, skip_bad=False, slop=0.005):
    """Measurements from a CSV file, a campaign log (.jsonl) or a rosbag2 directory / .db3 / .mcap."""
    p = Path(path)
    if is_recording(p):
        return read_rosbag(p, joint_names=joint_names, skip_bad=skip_bad, slop=slop)
    if p.suffix in (".jsonl", ".log"):
        return read_log(p, skip_bad=skip_bad)
    return read_csv(p, skip_bad=skip_bad)


"""The numerical libraries' thread pools are capped to one thread where the suite solves: in the command
line (from its first import) and inside ``allocate`` (also when the caller's pools are larger)."""
from __future__ import annotations

import json
import os
import subprocess
import sys

from threadpoolctl import threadpool_info, threadpool_limits

from tolerance_ros.core.models import DHChain
from tolerance_ros.core.synthesis import allocate
from tolerance_ros.core.threads import ENV_VARS


def pools():
    return {i["internal_api"]: i["num_threads"] for i in threadpool_info()}


def test_the_command_line_caps_the_pools_before_numpy_loads():
    env = {k: v for k, v in os.environ.items() if k not in ENV_VARS}
    code = ("import tolerance_ros.cli, json, numpy; from threadpoolctl import threadpool_info; "
            "print(json.dumps([i['num_threads'] for i in threadpool_info()]))")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    counts = json.loads(out)
    assert counts and set(counts) == {1}


def test_an_allocation_solves_on_one_thread_whatever_the_callers_pools():
    arm = DHChain("planar2r", a=[0.4, 0.3], alpha=[0, 0], d=[0, 0], theta=[0, 0])
    seen = []
    with threadpool_limits(limits=2):
        before = pools()
        allocate(arm, 1e-3, seed=0, n_mc=200, progress=lambda *a: seen.append(pools()))
        after = pools()
    assert seen and all(set(p.values()) == {1} for p in seen)
    assert after == before  # the caller's pools are restored

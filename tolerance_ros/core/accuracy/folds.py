"""The split of a campaign by test pose that every cross-validation shares (the calibration's candidates, the
choice of the registration): measurements grouped by test pose, the poses dealt into seeded folds."""
from __future__ import annotations

import numpy as np


def pose_groups(q, labels=None):
    """((n,) test-pose index of each measurement, names of the test poses in order of first visit): by
    label when the measurements carry two or more, else by equal joint values (named 'q1', 'q2', ...)."""
    keys = None
    if labels is not None:
        keys = np.asarray([str(v) for v in labels], dtype=object)
        if len(set(keys)) < 2:
            keys = None
    if keys is None:
        _, first, g = np.unique(np.round(np.asarray(q, float), 9), axis=0, return_index=True, return_inverse=True)
        names = None
    else:
        _, first, g = np.unique(keys, return_index=True, return_inverse=True)
        names = keys
    g = np.asarray(g, int).reshape(-1)
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    g = rank[g]
    labels_out = [str(names[first[i]]) if names is not None else f"q{j + 1}" for j, i in enumerate(order)]
    return g, labels_out


def folds_of(groups, folds, seed):
    """((n,) fold of each measurement, k): the test poses split into k = min(folds, poses) seeded folds."""
    uniq = np.unique(groups)
    if len(uniq) < 2:
        raise ValueError("validation: needs at least 2 distinct test poses (measure more poses)")
    k = int(min(folds, len(uniq)))
    if k < 2:
        raise ValueError("validation: folds must be >= 2")
    fold_of = np.empty(uniq.max() + 1, int)
    fold_of[np.random.default_rng(seed).permutation(uniq)] = np.arange(len(uniq)) % k
    return fold_of[groups], k

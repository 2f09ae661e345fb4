"""Streams as logs have them: stamps repeated, rows out of order, a clock that jumps or starts again.

``tidy`` puts one stream (its stamps, s, and optionally its rows of values) in order and says what it did,
so that nothing measured is dropped without a word:

- a row whose stamp (or a value) is not finite is left out (``not_finite``);
- a row whose stamp is earlier than the latest before it by at most ``REORDER_S`` is out of order: the
  stream is sorted (``reordered`` counts the rows that arrived late);
- a row whose stamp repeats an earlier one (a driver that publishes a state twice) is a repeat: the first
  is kept (``repeated``; ``conflicting`` counts the repeats whose values differ from the kept row);
- a stamp more than ``REORDER_S`` before the latest one (a clock that started again) or more than
  ``JUMP_S`` after it (a clock that jumped) cuts the stream into epochs (``jumps``: where, from and to);
  an epoch of fewer than ``MIN_EPOCH_ROWS`` rows (a stray stamp) is left out (``stray``), and the stream is
  cut again without it, so that a stray stamp cuts nothing (one stamp of 1e308 amid a stream is one row left
  out, not two epochs).

``Timeline`` lays the joint states' epochs end to end, ``SEPARATION_S`` apart, and puts each tracker point in
the epoch of the joint states its own epoch overlaps (with one joint epoch, the tracker's longest epoch when
none overlaps: a trajectory's run time against the tracker's clock): one report judges every epoch with one latency and
one registration, in memory bounded by the number of rows whatever the time span. The work is vectorised:
the cost grows with the rows and the number of epochs, never with the seconds the stamps span.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

REORDER_S = 1.0        # s: a row at most this much earlier than the latest before it is out of order
JUMP_S = 60.0          # s: a step forward longer than this is a jump of the clock
MIN_EPOCH_ROWS = 3     # an epoch with fewer rows is a stray stamp
MAX_EPOCHS = 100       # more cuts than this: not a stream of one clock
MARGIN_S = 30.0        # s: a tracker point this far outside a joint epoch's span may still belong to it
SEPARATION_S = 4 * MARGIN_S   # s between the epochs laid end to end (no latency search reaches across)


@dataclass
class Tidied:
    """One stream put in order: ``epochs``, the row indices (into the stream as given) of each epoch, sorted by
    stamp, one row per stamp; the counts of what was done (see the module docstring)."""

    name: str
    rows: int
    epochs: list = field(default_factory=list)
    not_finite: int = 0
    reordered: int = 0
    repeated: int = 0
    conflicting: int = 0
    stray: int = 0
    jumps: list = field(default_factory=list)

    @property
    def kept(self) -> int:
        return int(sum(len(e) for e in self.epochs))

    def summary(self) -> dict:
        """JSON-ready: the stream's name, rows, kept, not_finite, reordered, repeated, conflicting, stray, epochs and the jumps
        (at most the first 10: row, from_s, to_s, by_s)."""
        return {"stream": self.name, "rows": self.rows, "kept": self.kept, "not_finite": self.not_finite, "reordered": self.reordered,
                "repeated": self.repeated, "conflicting": self.conflicting, "stray": self.stray,
                "epochs": len(self.epochs), "jumps": self.jumps[:10], "jump_count": len(self.jumps)}

    def describe(self) -> str | None:
        """One line for a person, or None when the stream was in order already."""
        return describe_tidied(self.name, self.summary())


def describe_tidied(name: str, s: dict) -> str | None:
    """The line of a ``Tidied.summary`` (also as read back from a JSON report), or None when nothing was done."""
    words = []
    if s["repeated"]:
        words.append(f"{s['repeated']:,} row(s) repeated a stamp (the first of each kept"
                     + (f"; {s['conflicting']:,} with other values" if s["conflicting"] else "") + ")")
    if s["reordered"]:
        words.append(f"{s['reordered']:,} row(s) out of order (sorted)")
    if s["not_finite"]:
        words.append(f"{s['not_finite']:,} row(s) without a finite stamp or value (left out)")
    for j in s["jumps"]:
        kind = "started again" if j["to_s"] < j["from_s"] else "jumped"
        words.append(f"the clock {kind} at row {j['row'] + 1:,} (from {j['from_s']:.6g} s to {j['to_s']:.6g} s, "
                     f"{j['by_s']:+.4g} s): the stream was cut there")
    if s["jump_count"] > len(s["jumps"]):
        words.append(f"{s['jump_count'] - len(s['jumps'])} more jump(s)")
    if s["stray"]:
        words.append(f"{s['stray']:,} row(s) on a clock of their own (stray stamps, left out; they cut nothing)")
    return f"{s.get('stream', name)}: " + "; ".join(words) if words else None


def tidy(stamps, values=None, name: str = "stream", min_rows: int = MIN_EPOCH_ROWS) -> Tidied:
    """The stream of ``stamps`` (n,) s in arrival order, with ``values`` (n, ...) beside (compared for
    repeats), put in order (module docstring); an epoch needs ``min_rows`` rows. ValueError when the clock
    jumps more than ``MAX_EPOCHS`` times."""
    t = np.asarray(stamps, dtype=float).reshape(-1)
    out = Tidied(name, int(t.size))
    if not t.size:
        return out
    good = np.isfinite(t)
    V = None
    if values is not None:
        V = np.asarray(values, dtype=float).reshape(t.size, -1)
        good &= np.all(np.isfinite(V), axis=1)
    idx = np.flatnonzero(good)
    out.not_finite = int(t.size - idx.size)
    while True:   # stray rows left out, the stream is cut again without them: they cut nothing
        out.jumps, out.epochs, out.reordered, out.repeated, out.conflicting = [], [], 0, 0, 0
        pieces = _cut(out, t, V, idx, name, min_rows)
        stray = [k for k, p in enumerate(pieces) if p[3]]
        if not stray:
            return out
        # first the stray pieces that interrupt one clock (the pieces either side of them would join: the stamp
        # after them follows the one before within the bounds of a step); else every stray piece
        joins = [k for k in stray if 0 < k < len(pieces) - 1
                 and -REORDER_S <= pieces[k + 1][1] - pieces[k - 1][2] <= JUMP_S]
        drop = np.concatenate([pieces[k][0] for k in (joins or stray)])
        out.stray += int(drop.size)
        idx = np.setdiff1d(idx, drop)


def _cut(out: Tidied, t, V, idx, name, min_rows) -> list:
    """Cut the rows ``idx`` of ``t`` at the jumps of the clock into ``out.epochs`` (each in order, one row per
    stamp) with the counts; returns every piece cut, in arrival order, as (its rows kept, its first stamp as
    it arrived, its latest stamp, whether it is stray: shorter than ``min_rows``, and not an epoch)."""
    tf = t[idx]
    starts = [0]
    while idx.size and starts[-1] < tf.size - 1:
        a = starts[-1]
        M = np.maximum.accumulate(tf[a:-1])
        step = tf[a + 1:]
        bad = np.flatnonzero((step < M - REORDER_S) | (step > M + JUMP_S))
        if not bad.size:
            break
        k = a + 1 + int(bad[0])
        if len(starts) > MAX_EPOCHS:
            raise ValueError(f"{name}: the clock jumps more than {MAX_EPOCHS} times (by more than {JUMP_S:g} s "
                             f"forward or {REORDER_S:g} s back): not a stream of one clock")
        out.jumps.append({"row": int(idx[k]), "from_s": float(M[k - a - 1]), "to_s": float(tf[k]),
                          "by_s": float(tf[k] - M[k - a - 1])})
        starts.append(k)
    pieces = []
    for a, b in zip(starts, starts[1:] + [tf.size]):
        seg = tf[a:b]
        if seg.size == 0:
            continue
        order = np.argsort(seg, kind="stable")
        s = seg[order]
        rep = np.concatenate([[False], s[1:] == s[:-1]])
        keep = idx[a + order[~rep]]
        pieces.append((keep, float(seg[0]), float(s[-1]), keep.size < min_rows))
        if keep.size < min_rows:
            continue
        out.reordered += int(np.count_nonzero(seg[1:] < np.maximum.accumulate(seg[:-1])))
        if rep.any():
            out.repeated += int(np.count_nonzero(rep))
            if V is not None:
                first = np.maximum.accumulate(np.where(rep, 0, np.arange(s.size)))   # each row's kept row
                rows = idx[a + order]
                differ = np.any(V[rows] != V[rows[first]], axis=1)
                out.conflicting += int(np.count_nonzero(differ & rep))
        out.epochs.append(keep)
    return pieces


def _overlap(a0, a1, b0, b1) -> float:
    return max(0.0, min(a1, b1) - max(a0, b0))


class Timeline:
    """The two streams of a path report on one clock (module docstring): ``tj`` (k,) s and ``ij`` (k,) the
    joint rows, ``tm`` (n,) s and ``im`` (n,) the tracker rows, both increasing; ``joint_slices`` and
    ``point_slices``, each epoch's part of them; ``outside``, the tracker rows kept by ``tidy`` that no
    joint epoch takes; ``shifts`` (s), what each joint epoch's stamps were moved by (0 for the first)."""

    def __init__(self, joints: Tidied, tj, points: Tidied, tm, margin: float = MARGIN_S):
        tj, tm = np.asarray(tj, float), np.asarray(tm, float)
        if not joints.epochs:
            raise ValueError(f"{joints.name}: no stamps to judge ({joints.describe() or 'empty'})")
        spans = [(float(tj[e[0]]), float(tj[e[-1]])) for e in joints.epochs]
        self.shifts, end = [], None
        for a, b in spans:
            shift = 0.0 if end is None else a - (end + max(SEPARATION_S, 4 * margin))
            self.shifts.append(shift)
            end = b - shift
        self.ij = np.concatenate(joints.epochs)
        self.tj = np.concatenate([tj[e] - s for e, s in zip(joints.epochs, self.shifts)])
        edges = np.cumsum([0] + [len(e) for e in joints.epochs])
        self.joint_slices = [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]
        pspans = [(float(tm[f[0]]), float(tm[f[-1]])) for f in points.epochs]
        pairs = sorted(((_overlap(p0, p1, a - margin, b + margin), k, f)
                        for f, (p0, p1) in enumerate(pspans) for k, (a, b) in enumerate(spans)), reverse=True)
        source = [None] * len(spans)            # each joint epoch takes the points of one tracker epoch
        for ov, k, f in pairs:
            if ov > 0 and source[k] is None:
                source[k] = f
        one = len(spans) == 1
        if one and source[0] is None and points.epochs:   # one clock each, offset (a trajectory's run time)
            source[0] = int(np.argmax([len(f) for f in points.epochs]))
        taken = [[] for _ in spans]
        for f, rows in enumerate(points.epochs):
            mine = [k for k in range(len(spans)) if source[k] == f]
            if not mine:
                continue
            t = tm[rows]
            owner = np.full(rows.size, -1)
            for k in sorted(mine, key=lambda k: -_overlap(*pspans[f], spans[k][0] - margin, spans[k][1] + margin)):
                a, b = spans[k]
                inside = owner < 0 if one else (owner < 0) & (t >= a - margin) & (t <= b + margin)
                owner[inside] = k
            for k in mine:
                taken[k].append(rows[owner == k])
        per = [r[0] if r else np.zeros(0, int) for r in taken]   # one tracker epoch each: in time order
        self.im = np.concatenate(per).astype(int) if per else np.zeros(0, int)
        self.tm = np.concatenate([tm[r] - s for r, s in zip(per, self.shifts)]) if per else np.zeros(0)
        edges = np.cumsum([0] + [len(r) for r in per])
        self.point_slices = [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]
        self.outside = int(points.kept - self.im.size)

    def covered(self, t, lo: float = 0.0, hi: float = 0.0) -> np.ndarray:
        """(n,) whether ``t - x`` (``t`` (n,) s on this timeline) lies within one epoch of the joint states for every
        shift ``x`` in ``[lo, hi]`` s."""
        t = np.asarray(t, float)
        starts = self.tj[[s.start for s in self.joint_slices]]
        ends = self.tj[[s.stop - 1 for s in self.joint_slices]]
        k = np.clip(np.searchsorted(starts, t - hi, side="right") - 1, 0, len(starts) - 1)
        return (t - hi >= starts[k]) & (t - lo <= ends[k])

    def original(self, t: float) -> float:
        """The stamp (s) as the joint states had it of a time ``t`` (s) on this timeline."""
        k = int(np.clip(np.searchsorted(self.tj[[s.start for s in self.joint_slices]], t, side="right") - 1, 0,
                        len(self.shifts) - 1))
        return float(t + self.shifts[k])


class LiveOrder:
    """One live stream put in order batch by batch (``tidy`` on line). ``take`` returns the batch's rows to use,
    in order, as ``(restart, stamps, values)`` pieces: ``restart`` when the piece starts a new clock (a jump or a
    restart against the rows taken before; confirmed by ``MIN_EPOCH_ROWS`` rows, so that one stray stamp
    is left out instead). A row not after the latest one taken is left out: ``repeated`` when its stamp
    equals one taken, ``late`` when earlier (by at most ``REORDER_S``: it arrived after later ones were
    used). ``counts`` and the latest ``jumps`` say what was done; nothing here raises."""

    def __init__(self, name: str):
        self.name = name
        self.last = None
        self.held = None           # rows on a new clock not yet confirmed: (stamps, values)
        self.counts = {"not_finite": 0, "reordered": 0, "repeated": 0, "conflicting": 0, "late": 0, "stray": 0,
                       "jumps": 0}
        self.jumps = []

    def take(self, stamps, values) -> list:
        t = np.asarray(stamps, dtype=float).reshape(-1)
        if not t.size:
            return []
        V = np.asarray(values, dtype=float).reshape(t.size, -1)
        if self.held is not None:
            t, V = np.concatenate([self.held[0], t]), np.concatenate([self.held[1], V])
            self.held = None
        td = tidy(t, V, self.name, min_rows=1)
        for key in ("not_finite", "reordered", "repeated", "conflicting"):
            self.counts[key] += getattr(td, key)
        out = []
        for k, e in enumerate(td.epochs):
            te, Ve = t[e], V[e]
            jump = self.last is not None and (te[0] < self.last - REORDER_S or te[0] > self.last + JUMP_S)
            if jump and len(te) < MIN_EPOCH_ROWS:
                if k == len(td.epochs) - 1:
                    self.held = (te, Ve)             # confirmed, or left out, by the rows after it
                else:
                    self.counts["stray"] += len(te)
                continue
            if jump:
                self.counts["jumps"] += 1
                self.jumps = (self.jumps + [{"from_s": float(self.last), "to_s": float(te[0]),
                                             "by_s": float(te[0] - self.last)}])[-10:]
            elif self.last is not None:
                new = te > self.last
                self.counts["repeated"] += int(np.count_nonzero(te == self.last))
                self.counts["late"] += int(np.count_nonzero(te < self.last))
                te, Ve = te[new], Ve[new]
                if not te.size:
                    continue
            out.append((jump, te, Ve))
            self.last = float(te[-1])
        return out

    def describe(self) -> str | None:
        """One line for a status message, or None when every row was taken in order."""
        c = self.counts
        words = [f"{c[k]:,} {w}" for k, w in (("repeated", "repeated stamp(s) left out"),
                                               ("late", "row(s) too late (after later ones were used)"),
                                               ("reordered", "row(s) out of order within a batch (sorted)"),
                                               ("not_finite", "row(s) not finite"),
                                               ("stray", "stray stamp(s) on a clock of their own")) if c[k]]
        if c["jumps"]:
            j = self.jumps[-1]
            words.append(f"the clock jumped {c['jumps']} time(s), the latest from {j['from_s']:.6g} s to "
                         f"{j['to_s']:.6g} s: the stream started again there")
        return f"{self.name}: " + "; ".join(words) if words else None

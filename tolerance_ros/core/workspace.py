"""Where test poses may be: joint ranges within the limits, the tool above planes and inside a box, and no
collision of the links with each other or with those planes (where the URDF has collision geometry).

Restrictions are written as on the command line, each length or angle with its unit:

- joint range ``NAME=LO:HI`` (``shoulder_lift_joint=-180deg:0deg``; a prismatic joint in lengths);
- plane ``NX,NY,NZ@OFFSET`` (``0,0,1@0.05m``): the points p of the base frame with ``n . p >= OFFSET``
  (n normalised) are allowed; the tool point and every moving link's collision geometry must stay there;
- box ``XMIN:XMAX,YMIN:YMAX,ZMIN:ZMAX`` (``0.2m:1.2m,-0.6m:0.6m,0m:1m``): the tool point stays inside it;
- clearance (``0.01m``): the least distance of the moving links' geometry from the planes.

Self-collision is checked between every pair of links' collision geometry except adjacent links (one joint
apart, or on the same joint), and either the pairs an SRDF disables or, without one, the pairs already in
contact at the zero configuration (touching by design). Links fixed to the base are not checked against
the planes (they are mounted there). All lengths in m, angles in rad inside.
"""
from __future__ import annotations

import difflib
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .resources import not_a_file
from .units import UnitError, parse_quantity

FIRST_REASONS = ("joint range", "tool below a plane", "tool outside the box", "link through a plane",
                 "self-collision")


class WorkspaceError(ValueError):
    """An invalid restriction, or collision geometry that cannot be loaded; the message names the option."""


def _quantity(text, kind, field):
    try:
        return parse_quantity(text.strip(), kind, field=field)
    except UnitError as exc:
        raise WorkspaceError(str(exc)) from None


def parse_joint_range(text: str, model, field="--joint-range") -> tuple:
    """(joint index, lo, hi) SI of ``NAME=LO:HI``; the range must lie within the model's joint limits."""
    name, eq, rng = str(text).partition("=")
    name = name.strip()
    if not eq or ":" not in rng:
        raise WorkspaceError(f"{field}: expected NAME=LO:HI with units, e.g. {model.joint_names[0]}=-90deg:90deg, "
                             f"got {text!r}")
    if name not in model.joint_names:
        close = difflib.get_close_matches(name, model.joint_names, n=1, cutoff=0.0)
        raise WorkspaceError(f"{field}: robot {model.name!r} has no joint {name!r} (closest: {close[0]!r}; "
                             f"joints: {', '.join(model.joint_names)})")
    k = model.joint_names.index(name)
    kind = "length" if model.joint_types[k] == "prismatic" else "angle"
    lo_t, _, hi_t = rng.partition(":")
    lo, hi = _quantity(lo_t, kind, f"{field} {name} low"), _quantity(hi_t, kind, f"{field} {name} high")
    if not lo < hi:
        raise WorkspaceError(f"{field} {name}: the low end {lo_t.strip()} must be below the high end {hi_t.strip()}")
    llo, lhi = model.joint_limits[k]
    if lo < llo - 1e-12 or hi > lhi + 1e-12:
        scale, unit = (1.0, "m") if kind == "length" else (np.pi / 180, "deg")
        raise WorkspaceError(f"{field} {name}: {lo_t.strip()}:{hi_t.strip()} is outside the joint's limits "
                             f"[{llo / scale:.6g}, {lhi / scale:.6g}] {unit}")
    return k, lo, hi


def parse_plane(text: str, field="--above-plane") -> tuple:
    """(unit normal (3,), offset m) of ``NX,NY,NZ@OFFSET``: the allowed side is ``n . p >= offset``."""
    normal, at, offset = str(text).partition("@")
    parts = normal.split(",")
    if not at or len(parts) != 3:
        raise WorkspaceError(f"{field}: expected NX,NY,NZ@OFFSET (the normal, then the offset with its unit), "
                             f"e.g. 0,0,1@0.05m for z >= 0.05 m, got {text!r}")
    try:
        n = np.array([float(p) for p in parts])
    except ValueError:
        raise WorkspaceError(f"{field}: the normal {normal!r} must be three plain numbers, e.g. 0,0,1") from None
    size = np.linalg.norm(n)
    if not (np.isfinite(size) and size > 0):
        raise WorkspaceError(f"{field}: the normal {normal!r} must be finite and nonzero")
    return n / size, _quantity(offset, "length", f"{field} offset")


def parse_box(text: str, field="--inside-box") -> np.ndarray:
    """(3, 2) [min, max] m per axis of ``XMIN:XMAX,YMIN:YMAX,ZMIN:ZMAX``."""
    parts = str(text).split(",")
    if len(parts) != 3 or not all(":" in p for p in parts):
        raise WorkspaceError(f"{field}: expected XMIN:XMAX,YMIN:YMAX,ZMIN:ZMAX with units, e.g. "
                             f"0.2m:1.2m,-0.6m:0.6m,0m:1m, got {text!r}")
    box = np.empty((3, 2))
    for i, (axis, p) in enumerate(zip("xyz", parts)):
        lo, _, hi = p.partition(":")
        box[i] = _quantity(lo, "length", f"{field} {axis}min"), _quantity(hi, "length", f"{field} {axis}max")
        if not box[i, 0] < box[i, 1]:
            raise WorkspaceError(f"{field}: {axis}min {lo.strip()} must be below {axis}max {hi.strip()}")
    return box


@dataclass
class Restrictions:
    """Restrictions on test poses (see the module docstring), SI, with the texts they were read from."""

    limits: np.ndarray                       # (dof, 2) joint ranges: the model's limits where none is given
    planes: list = field(default_factory=list)  # [(unit normal (3,), offset m)]
    box: np.ndarray | None = None            # (3, 2) m
    clearance: float = 0.0                   # m
    collision: bool = True
    srdf: str | None = None
    texts: dict = field(default_factory=dict)

    @property
    def any_tool(self) -> bool:
        """Whether the tool position is restricted (a plane or the box)."""
        return bool(self.planes) or self.box is not None


def restrictions(model, joint_range=(), above_plane=(), floor=None, inside_box=None, clearance=None,
                 collision=True, srdf=None) -> Restrictions:
    """Restrictions from their texts (the module docstring's forms; ``floor`` Z is the plane ``0,0,1@Z``).
    ``texts`` keeps them in the campaign file's ``restrictions`` form."""
    limits = np.array(model.joint_limits, dtype=float)
    seen = {}
    for t in joint_range or ():
        k, lo, hi = parse_joint_range(t, model)
        if k in seen:
            raise WorkspaceError(f"--joint-range: {model.joint_names[k]} is given twice ({seen[k]!r}, {t!r})")
        seen[k] = t
        limits[k] = lo, hi
    plane_texts = [str(t).strip() for t in above_plane or ()]
    planes = [parse_plane(t) for t in plane_texts]
    if floor is not None:
        _quantity(floor, "length", "--floor-plane")
        plane_texts.append(f"0,0,1@{str(floor).strip()}")
        planes.append(parse_plane(plane_texts[-1], "--floor-plane"))
    box = parse_box(inside_box) if inside_box is not None else None
    clear = 0.0
    if clearance is not None:
        clear = _quantity(clearance, "length", "--clearance")
        if clear < 0:
            raise WorkspaceError(f"--clearance: must be >= 0, got {clearance!r}")
    if srdf is not None and not Path(srdf).is_file():
        raise WorkspaceError(f"--srdf: {not_a_file(srdf)}: {srdf}")
    texts = {"joint_range": [seen[k].strip() for k in sorted(seen)], "above_plane": plane_texts,
             "inside_box": inside_box.strip() if inside_box is not None else None,
             "clearance": clearance.strip() if clearance is not None else None, "collision": bool(collision),
             "srdf": str(Path(srdf).resolve()) if srdf is not None else None}
    return Restrictions(limits, planes, box, clear, bool(collision), srdf, texts)


RESTRICTION_KEYS = {"joint_range", "above_plane", "inside_box", "clearance", "collision", "srdf"}


def restrictions_from_dict(model, data, field="restrictions") -> Restrictions:
    """Restrictions from a campaign file's ``restrictions`` mapping (the keys of ``Restrictions.texts``)."""
    if not isinstance(data, dict):
        raise WorkspaceError(f"{field}: expected a mapping with keys {sorted(RESTRICTION_KEYS)}")
    bad = sorted(set(data) - RESTRICTION_KEYS)
    if bad:
        raise WorkspaceError(f"{field}: unknown key(s) {bad}; allowed: {sorted(RESTRICTION_KEYS)}")
    lists = {}
    for key in ("joint_range", "above_plane"):
        v = data.get(key) or []
        if not isinstance(v, list) or not all(isinstance(t, str) for t in v):
            raise WorkspaceError(f"{field}.{key}: expected a list of strings")
        lists[key] = v
    for key in ("inside_box", "clearance", "srdf"):
        if data.get(key) is not None and not isinstance(data[key], str):
            raise WorkspaceError(f"{field}.{key}: expected a string with units")
    if not isinstance(data.get("collision", True), bool):
        raise WorkspaceError(f"{field}.collision: expected true or false")
    try:
        return restrictions(model, lists["joint_range"], lists["above_plane"], None, data.get("inside_box"),
                            data.get("clearance"), data.get("collision", True), data.get("srdf"))
    except WorkspaceError as exc:  # the file's keys, not the command line's options
        msg = str(exc)
        for key in RESTRICTION_KEYS:
            msg = msg.replace("--" + key.replace("_", "-"), f"{field}.{key}")
        raise WorkspaceError(msg) from None


def _package_dirs(source: str) -> list:
    """Folders that may hold the ``package://NAME/...`` of a URDF file: each ancestor folder's parent (the
    URDF inside its package), then ROS_PACKAGE_PATH and AMENT_PREFIX_PATH's share folders."""
    out = []
    if source != "<string>":
        out += [str(p.parent) for p in Path(source).resolve().parents if p.parent != p]
    out += [p for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
    out += [str(Path(p) / "share") for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    return out


def _support_points(geom) -> tuple:
    """(points (k, 3) in the geometry's frame, radius m): the geometry is within ``radius`` of the points'
    convex hull, and reaches it (meshes: vertices; box: corners; sphere, capsule; cylinder: two rings of
    64 points; other shapes: the corners of their local bounding box)."""
    kind = type(geom).__name__
    if hasattr(geom, "vertices") and kind.startswith(("BVHModel", "Convex")):
        return np.asarray(geom.vertices(), float).reshape(-1, 3), 0.0
    if kind == "Box":
        return np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T * np.asarray(geom.halfSide), 0.0
    if kind == "Sphere":
        return np.zeros((1, 3)), float(geom.radius)
    if kind == "Capsule":
        return np.array([[0, 0, -geom.halfLength], [0, 0, geom.halfLength]]), float(geom.radius)
    if kind == "Cylinder":
        a = np.linspace(0, 2 * np.pi, 64, endpoint=False)
        ring = np.c_[geom.radius * np.cos(a), geom.radius * np.sin(a)]
        return np.r_[np.c_[ring, np.full(64, -geom.halfLength)], np.c_[ring, np.full(64, geom.halfLength)]], 0.0
    geom.computeLocalAABB()
    lo, hi = np.asarray(geom.aabb_local.min_), np.asarray(geom.aabb_local.max_)
    return np.array(np.meshgrid(*zip(lo, hi))).reshape(3, -1).T, 0.0


class CollisionModel:
    """Collision geometry of a URDF chain (pinocchio + coal): self-collision pairs and the support points of
    the links the chain moves (see the module docstring)."""

    def __init__(self, model, geom, srdf=None):
        import pinocchio as pin
        self.pin, self.model, self.geom = pin, model, geom
        pm = model.pin_model
        objs = geom.geometryObjects
        geom.addAllCollisionPairs()
        par = pm.parents

        def adjacent(cp):
            a, b = objs[cp.first].parentJoint, objs[cp.second].parentJoint
            return a == b or par[a] == b or par[b] == a
        for cp in [pin.CollisionPair(cp.first, cp.second) for cp in geom.collisionPairs if adjacent(cp)]:
            geom.removeCollisionPair(cp)
        self.pdata, self.gdata = pm.createData(), geom.createData()
        if srdf is not None:
            pin.removeCollisionPairs(pm, geom, str(srdf))
            self.excluded = f"adjacent links and the pairs {Path(srdf).name} disables"
        else:
            zero = np.clip(np.zeros(model.dof), model.joint_limits[:, 0], model.joint_limits[:, 1])
            touching = [pin.CollisionPair(cp.first, cp.second)
                        for cp, hit in zip(geom.collisionPairs, self._pair_hits(zero)) if hit]
            for cp in touching:
                geom.removeCollisionPair(cp)
            self.excluded = "adjacent links" + (f" and the pairs in contact at the zero configuration "
                                                f"({', '.join(self._pair_name(cp) for cp in touching)})"
                                                if touching else "")
        self.gdata = geom.createData()
        self.pairs = [self._pair_name(cp) for cp in geom.collisionPairs]
        chain = set(model.chain_ids)

        def moved(j):
            while j > 0:
                if j in chain:
                    return True
                j = par[j]
            return False
        self.moving = [i for i, o in enumerate(objs) if moved(o.parentJoint)]
        self.support = [_support_points(objs[i].geometry) for i in self.moving]
        self.links = [objs[i].name for i in self.moving]
        self.base_from_root = np.asarray(model.base_from_root, float)
        self.base_frame = model.pin_model.getFrameId(model.base_link) if getattr(model, "base_moves", False) else None

    def _pair_name(self, cp) -> str:
        objs = self.geom.geometryObjects
        return f"{_link(objs[cp.first].name)}-{_link(objs[cp.second].name)}"

    def _pair_hits(self, q) -> list:
        """Collision of each pair at one configuration q (dof,)."""
        self.pin.computeCollisions(self.model.pin_model, self.pdata, self.geom, self.gdata,
                                   self.model.pinocchio_configuration(q), False)
        return [r.isCollision() for r in self.gdata.collisionResults]

    def check(self, q, tick=None, chunk=200) -> tuple:
        """((n, pairs) self-collision per pair, (n, moving links, 4, 4) placements of their geometry in the
        model's base frame, m) at the configurations q (n, dof); ``tick(fraction done)`` every ``chunk``."""
        q = np.atleast_2d(q)
        hits = np.zeros((len(q), len(self.pairs)), bool)
        place = np.empty((len(q), len(self.moving), 4, 4))
        oMg = self.gdata.oMg
        to_base = np.repeat(self.base_from_root[None], len(q), axis=0)
        for i, qi in enumerate(q):
            hits[i] = self._pair_hits(qi)
            for j, g in enumerate(self.moving):
                place[i, j] = oMg[g].homogeneous
            if self.base_frame is not None:   # a base link moved by joints: its frame at this configuration
                to_base[i] = self.pin.updateFramePlacement(self.model.pin_model, self.pdata,
                                                           self.base_frame).inverse().homogeneous
            if tick is not None and (i + 1) % chunk == 0:
                tick((i + 1) / len(q))
        return hits, np.einsum("nij,nkjl->nkil", to_base, place)

    def plane_heights(self, place, planes) -> np.ndarray:
        """(n, planes, moving links) least signed distance m of each link's geometry above each plane."""
        out = np.empty((len(place), len(planes), len(self.moving)))
        for j, (pts, radius) in enumerate(self.support):
            R, t = place[:, j, :3, :3], place[:, j, :3, 3]
            for p, (normal, offset) in enumerate(planes):
                w = np.einsum("nji,j->ni", R, normal)
                out[:, p, j] = t @ normal + (w @ pts.T).min(axis=1) - radius - offset
        return out


def _link(geom_name: str) -> str:
    """The link of a pinocchio geometry object's name (``upper_arm_link_0`` -> ``upper_arm_link``)."""
    head, _, tail = geom_name.rpartition("_")
    return head if tail.isdigit() and head else geom_name


def collision_model(model, srdf=None, off="plan with --no-collision") -> tuple:
    """(CollisionModel or None, note): the URDF chain's collision geometry; None (and why) for a robot
    without any. WorkspaceError when its meshes cannot be found (saying: put them on ROS_PACKAGE_PATH, or
    ``off``, how to not check collisions)."""
    if not hasattr(model, "pin_model") or not hasattr(model, "chain_ids"):
        return None, f"no collision geometry (robot {model.name!r} is a {type(model).__name__}): collisions not checked"
    import pinocchio as pin
    text, source = model.urdf_text, model.source
    if "<collision" not in text:
        return None, "no collision geometry in the URDF: collisions not checked"
    try:
        geom = pin.buildGeomFromUrdfString(model.pin_model, text, pin.GeometryType.COLLISION,
                                           package_dirs=_package_dirs(source))
    except ValueError as exc:
        raise WorkspaceError(f"collision geometry of {source}: {exc} (put its package's folder on ROS_PACKAGE_PATH, "
                             f"or {off})") from None
    if not len(geom.geometryObjects):
        return None, "no collision geometry in the URDF: collisions not checked"
    cm = CollisionModel(model, geom, srdf)
    return cm, (f"collision geometry of {len(geom.geometryObjects)} objects: {len(cm.pairs)} link pairs checked for "
                f"self-collision (not {cm.excluded})")


@dataclass
class Verdict:
    """The check of n poses: ``ok`` (n,), the first reason each failing pose fails (n,) ('' if ok), and
    details per pose (the plane, the link or the link pair)."""

    ok: np.ndarray
    reason: np.ndarray
    detail: np.ndarray

    def counts(self) -> dict:
        """{reason: number of poses failing first for it}, in the order of ``FIRST_REASONS``."""
        return {r: int(np.sum(self.reason == r)) for r in FIRST_REASONS if np.any(self.reason == r)}


class Workspace:
    """The restrictions applied to a model: ``check`` poses, ``sample`` candidates that pass."""

    def __init__(self, model, rest: Restrictions, off="plan with --no-collision"):
        """``off``: how to not check collisions, for the message when the meshes cannot be found."""
        self.model, self.rest = model, rest
        self.collider, self.collision_note = (collision_model(model, rest.srdf, off) if rest.collision
                                              else (None, "collisions not checked (--no-collision)"))
        narrowed = not np.array_equal(rest.limits, model.joint_limits)
        self._sampler = model.with_joint_limits(rest.limits) if narrowed else model

    def describe(self) -> str:
        """One line of the restrictions, as written (for messages and campaign descriptions)."""
        t = self.rest.texts
        parts = [f"joint range {r}" for r in t["joint_range"]] + [f"above plane {p}" for p in t["above_plane"]]
        if t["inside_box"]:
            parts.append(f"tool inside box {t['inside_box']}")
        if t["clearance"]:
            parts.append(f"clearance {t['clearance']}")
        parts.append("no self-collision or link through a plane" if self.collider is not None else
                     self.collision_note)
        return "; ".join(parts)

    def to_dict(self) -> dict:
        """The restrictions as written, the joint ranges (dof, 2) SI and what the collision check covers."""
        return {**self.rest.texts, "limits": self.rest.limits, "collision_checked": self.collider is not None,
                "collision_note": self.collision_note,
                "self_collision_pairs": self.collider.pairs if self.collider is not None else []}

    def check(self, q, tick=None) -> Verdict:
        """Verdict of the poses q (n, dof) SI: joint ranges, then the tool against the planes and the box, then
        (on the poses left) the links against the planes and each other."""
        q = np.atleast_2d(np.asarray(q, float))
        n = len(q)
        reason, detail = np.full(n, "", dtype=object), np.full(n, "", dtype=object)

        def fail(mask, why, what):
            new = mask & (reason == "")
            reason[new] = why
            detail[new] = what[new] if isinstance(what, np.ndarray) else what
        lim, names = self.rest.limits, np.array(self.model.joint_names, dtype=object)
        out = (q < lim[:, 0] - 1e-12) | (q > lim[:, 1] + 1e-12)
        fail(out.any(axis=1), "joint range", names[np.argmax(out, axis=1)])
        if self.rest.any_tool:
            P = self.model.fk(q)[:, :3, 3]
            for (normal, offset), text in zip(self.rest.planes, self.rest.texts["above_plane"]):
                fail(P @ normal < offset, "tool below a plane", text)
            if self.rest.box is not None:
                below, above = P < self.rest.box[:, 0], P > self.rest.box[:, 1]
                ends = [p.split(":") for p in self.rest.texts["inside_box"].split(",")]
                sides = np.array([f"{a} < {ends[i][0].strip()}" for i, a in enumerate("xyz")] +
                                 [f"{a} > {ends[i][1].strip()}" for i, a in enumerate("xyz")], dtype=object)
                fail((below | above).any(axis=1), "tool outside the box", sides[np.argmax(np.c_[below, above], 1)])
        if self.collider is not None:
            left = np.flatnonzero(reason == "")
            if len(left):
                hits, place = self.collider.check(q[left], tick)
                if self.rest.planes:
                    h = self.collider.plane_heights(place, self.rest.planes)
                    low = h < self.rest.clearance
                    for p, text in enumerate(self.rest.texts["above_plane"]):
                        m = np.zeros(n, bool)
                        m[left] = low[:, p].any(axis=1)
                        links = np.full(n, "", dtype=object)
                        links[left] = [f"{_link(self.collider.links[j])} through {text}"
                                       for j in np.argmax(low[:, p], 1)]
                        fail(m, "link through a plane", links)
                m = np.zeros(n, bool)
                m[left] = hits.any(axis=1)
                pairs = np.full(n, "", dtype=object)
                pairs[left] = [self.collider.pairs[j] if self.collider.pairs else "" for j in np.argmax(hits, 1)]
                fail(m, "self-collision", pairs)
        return Verdict(reason == "", reason, detail)

    def sample(self, m: int, rng, max_draws: int, tick=None) -> tuple:
        """((k, dof) the first k <= m poses drawn by the model's ``sample_joints`` (serial chains: uniformly)
        within the joint ranges that pass ``check``, report):
        draws in batches until m pass or ``max_draws`` are drawn. The report: drawn (up to the m-th pose
        kept), kept, rejected (first reason: count; they add up to drawn), details (per reason, the plane,
        the box side, the link or the link pair: count, most frequent first)."""
        kept, drawn, reasons, details = [], 0, {}, {}
        have = 0
        while have < m and drawn < max_draws:
            rate = have / drawn if drawn else 1.0
            size = int(min(max_draws - drawn, m if not drawn else max(64, 1.2 * (m - have) / max(rate, 0.01))))
            q = self._sampler.sample_joints(size, rng)
            done = drawn
            v = self.check(q, None if tick is None else (lambda f: tick((done + f * size) / max_draws)))
            passed = np.flatnonzero(v.ok)
            if have + len(passed) > m:  # the poses after the m-th passing one are not counted
                end = passed[m - have - 1] + 1
                q, v = q[:end], Verdict(v.ok[:end], v.reason[:end], v.detail[:end])
            drawn += len(q)
            kept.append(q[v.ok])
            have += int(v.ok.sum())
            for r, c in v.counts().items():
                reasons[r] = reasons.get(r, 0) + c
                what, count = np.unique(v.detail[v.reason == r].astype(str), return_counts=True)
                for d, c in zip(what, count):
                    details.setdefault(r, {})[d] = details.get(r, {}).get(d, 0) + int(c)
            if tick is not None:
                tick(drawn / max_draws if have < m else 1.0)
        q = np.concatenate(kept) if kept else np.empty((0, self.model.dof))
        return q, {"drawn": int(drawn), "kept": int(len(q)), "rejected": reasons,
                   "details": {r: dict(sorted(d.items(), key=lambda kv: -kv[1])) for r, d in details.items()}}

    def violations(self, q, names) -> list:
        """['NAME: reason (detail)'] for the poses q (n, dof) that fail ``check``."""
        v = self.check(q)
        return [f"{nm}: {r}" + (f" ({d})" if d else "") for nm, r, d, ok in zip(names, v.reason, v.detail, v.ok)
                if not ok]


def listed(violations: list, most: int = 5) -> str:
    """The first ``most`` of ``Workspace.violations``, '; '-separated, with '; ...' when there are more."""
    return "; ".join(violations[:most]) + ("; ..." if len(violations) > most else "")


def rejection_summary(report: dict) -> str:
    """'kept 1,412 of 2,000 candidates drawn: 430 tool below a plane (0,0,1@0m), 158 self-collision (most
    often shoulder_link-forearm_link)': each reason with its detail, or its most frequent one."""
    parts = []
    for r, c in report["rejected"].items():
        d = report["details"].get(r) or {"": 0}
        top = next(iter(d))
        parts.append(f"{c:,} {r}" + ("" if not top else f" ({top})" if len(d) == 1 else f" (most often {top})"))
    return f"kept {report['kept']:,} of {report['drawn']:,} candidates drawn" + (": " + ", ".join(parts) if parts
                                                                                  else "")

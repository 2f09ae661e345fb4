"""Compiled (numba) batched forward kinematics and parameter-error Jacobians of serial chains (D-H, URDF).

The numpy code of ``dh.py`` and ``urdf.py`` is the reference; these kernels compute the same poses and
columns pose by pose in one compiled loop. Shared arguments:

- ``q`` (n, dof) float64 joints (rad or m); ``nominal`` (p,) parameters; ``dx`` (m, p) parameter errors
  with m = 0 (none), 1 (shared by all poses) or n (one row per pose), SI;
- ``T`` (n, 4, 4) and ``J`` (n, 6, p) float64 outputs, filled in place (``J`` is ignored unless
  ``jacobian``); J's rows 0-2 are position (m per unit), rows 3-5 a small rotation in the base frame;
- the return value is -1, or the flat index of the first non-finite joint value (nothing computed then).

``dh_chain`` writes J column by column, in place (21 cache lines a pose; it gained nothing from other
writers). ``urdf_chain`` has three writers (its ``writer`` argument): 0 columns in place; 1 rows in memory
order; 2 rows in memory order with non-temporal (streaming) stores, which save the read of each cache line
before its write but can be far slower on some CPUs: ``jacobian_writers`` chooses per machine. Streaming is
fast only while nothing flushes the partly written cache lines: no atomic instruction (numba's reference
counting of an array passed to a helper) between the stores of one pose, and the stores in memory order;
variants that broke either were 1.5x and 20x slower.

Cached on disk as ``jit.njit`` says; ``kernels.warm_up`` compiles (or loads) every signature the models call.
"""
from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from .jit import NO_DX, NO_J, njit

__all__ = ["BLOCK", "NO_DX", "NO_J", "SINCOS_LIMIT", "dh_chain", "sincos", "urdf_chain", "urdf_either_way", "warm_up"]
"""What ``base.CompiledChain`` and the tests read from this module (``NO_DX`` and ``NO_J``: the kernels' empty
arrays, read here so that ``base`` imports no numba)."""

BLOCK = 64  # poses per block: their joint angles' sines and cosines are computed together (SIMD)

# sin and cos: reduction by pi/2 in three parts (Cody-Waite) and the fdlibm kernels' polynomials on
# [-pi/4, pi/4]; within 1 ulp of libm for |x| <= SINCOS_LIMIT, libm beyond.
SINCOS_LIMIT = 1e5
_INV_PIO2 = 6.36619772367581382433e-01
_PIO2_1 = 1.57079632673412561417e+00
_PIO2_2 = 6.07710050630396597660e-11
_PIO2_3 = 2.02226624871116645580e-21
_S1, _S2, _S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
_S4, _S5, _S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
_C1, _C2, _C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
_C4, _C5, _C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11


@njit
def sincos(x, s, c, m):
    """s[:m], c[:m] = sin(x[:m]), cos(x[:m]) (rad); a branch-free loop that the compiler vectorises."""
    for i in range(m):
        k = math.floor(x[i] * _INV_PIO2 + 0.5)
        r = ((x[i] - k * _PIO2_1) - k * _PIO2_2) - k * _PIO2_3
        z = r * r
        sr = r + r * z * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))))
        cr = 1.0 - 0.5 * z + z * z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6)))))
        quadrant = int(k) & 3
        sv = cr if quadrant & 1 else sr
        cv = sr if quadrant & 1 else cr
        s[i] = -sv if quadrant & 2 else sv
        c[i] = -cv if (quadrant + 1) & 2 else cv
    for i in range(m):
        if abs(x[i]) > SINCOS_LIMIT:
            s[i] = math.sin(x[i])
            c[i] = math.cos(x[i])


@intrinsic
def _stream(typingctx, flat, i, value):
    """flat[i] = value as a non-temporal store (a hint: a plain store where the target has none); ``flat`` a
    C-contiguous float64 array, ``i`` not checked."""
    if not (isinstance(flat, types.Array) and flat.layout == "C" and flat.dtype == types.float64):
        return None

    def codegen(context, builder, sig, args):
        ary = context.make_array(sig.args[0])(context, builder, args[0])
        bits = builder.bitcast(context.cast(builder, args[2], sig.args[2], types.float64), ir.IntType(64))
        store = builder.store(bits, builder.bitcast(builder.gep(ary.data, [args[1]]), ir.IntType(64).as_pointer()))
        store.set_metadata("nontemporal", builder.module.add_metadata([ir.Constant(ir.IntType(32), 1)]))
        return context.get_dummy_value()
    return types.void(flat, types.intp, value), codegen


@intrinsic
def _fence(typingctx):
    """A sequentially consistent fence: every store before it, streaming ones included, is visible after it."""
    def codegen(context, builder, sig, args):
        builder.fence("seq_cst")
        return context.get_dummy_value()
    return types.void(), codegen


@njit
def _first_nonfinite(q):
    n, dof = q.shape
    for k in range(n):
        for i in range(dof):
            if not math.isfinite(q[k, i]):
                return k * dof + i
    return -1


@njit
def _param(nominal, dx, row, j):
    if dx.shape[0] == 0:
        return nominal[j]
    return nominal[j] + dx[row, j]


@njit
def _angle_column(J, k, c, u0, u1, u2, r0, r1, r2):
    """Column c of pose k for a turn about unit (u0, u1, u2) through a point at -r from the tool point."""
    J[k, 0, c] = u1 * r2 - u2 * r1
    J[k, 1, c] = u2 * r0 - u0 * r2
    J[k, 2, c] = u0 * r1 - u1 * r0
    J[k, 3, c] = u0
    J[k, 4, c] = u1
    J[k, 5, c] = u2


@njit
def _length_column(J, k, c, u0, u1, u2):
    """Column c of pose k for a shift along unit (u0, u1, u2)."""
    J[k, 0, c] = u0
    J[k, 1, c] = u1
    J[k, 2, c] = u2
    J[k, 3, c] = 0.0
    J[k, 4, c] = 0.0
    J[k, 5, c] = 0.0


@njit
def _store_pose(T, k, x0, x1, x2, y0, y1, y2, z0, z1, z2, o0, o1, o2, tool):
    """T[k] = [x y z o; 0 0 0 1] (frame axes and origin, base frame) times the tool; returns the tool point."""
    for c in range(3):
        T[k, 0, c] = x0 * tool[0, c] + y0 * tool[1, c] + z0 * tool[2, c]
        T[k, 1, c] = x1 * tool[0, c] + y1 * tool[1, c] + z1 * tool[2, c]
        T[k, 2, c] = x2 * tool[0, c] + y2 * tool[1, c] + z2 * tool[2, c]
    p0 = o0 + x0 * tool[0, 3] + y0 * tool[1, 3] + z0 * tool[2, 3]
    p1 = o1 + x1 * tool[0, 3] + y1 * tool[1, 3] + z1 * tool[2, 3]
    p2 = o2 + x2 * tool[0, 3] + y2 * tool[1, 3] + z2 * tool[2, 3]
    T[k, 0, 3] = p0
    T[k, 1, 3] = p1
    T[k, 2, 3] = p2
    T[k, 3, 0] = 0.0
    T[k, 3, 1] = 0.0
    T[k, 3, 2] = 0.0
    T[k, 3, 3] = 1.0
    return p0, p1, p2


@njit
def dh_chain(q, nominal, dx, revolute, standard, base, tool, T, J, jacobian):
    """D-H chain (see dh.py): parameters a1..an, d1..dn, alpha1..alphan, theta1..thetan (m, rad)."""
    bad = _first_nonfinite(q)
    if bad >= 0:
        return bad
    n, dof = q.shape
    per_pose = dx.shape[0] > 1
    ca = np.empty(dof)          # cos and sin of the twists when they are the same for every pose
    sa = np.empty(dof)
    for i in range(dof):
        ca[i] = math.cos(_param(nominal, dx, 0, 2 * dof + i))
        sa[i] = math.sin(_param(nominal, dx, 0, 2 * dof + i))
    width = 2 * dof if per_pose else dof   # angles per pose: theta_i (+ alpha_i when per pose)
    ang = np.empty(BLOCK * width)
    sn = np.empty(BLOCK * width)
    cs = np.empty(BLOCK * width)
    ax = np.empty((dof, 6))     # line of a_i and alpha_i: unit vector, point (base frame)
    az = np.empty((dof, 6))     # line of d_i and theta_i: unit vector, point (base frame)
    for k0 in range(0, n, BLOCK):
        m = min(BLOCK, n - k0)
        for b in range(m):
            k = k0 + b
            row = k if per_pose else 0
            for i in range(dof):
                th = _param(nominal, dx, row, 3 * dof + i)
                ang[b * width + i] = q[k, i] + th if revolute[i] else th
                if per_pose:
                    ang[b * width + dof + i] = _param(nominal, dx, row, 2 * dof + i)
        sincos(ang, sn, cs, m * width)
        for b in range(m):
            k = k0 + b
            row = k if per_pose else 0
            x0, x1, x2 = base[0, 0], base[1, 0], base[2, 0]
            y0, y1, y2 = base[0, 1], base[1, 1], base[2, 1]
            z0, z1, z2 = base[0, 2], base[1, 2], base[2, 2]
            o0, o1, o2 = base[0, 3], base[1, 3], base[2, 3]
            for i in range(dof):
                ct, st = cs[b * width + i], sn[b * width + i]
                if per_pose:
                    c, s = cs[b * width + dof + i], sn[b * width + dof + i]
                else:
                    c, s = ca[i], sa[i]
                ai = _param(nominal, dx, row, i)
                di = _param(nominal, dx, row, dof + i)
                if not revolute[i]:
                    di = q[k, i] + di
                if standard:
                    az[i, 0], az[i, 1], az[i, 2], az[i, 3], az[i, 4], az[i, 5] = z0, z1, z2, o0, o1, o2
                    xn0, xn1, xn2 = ct * x0 + st * y0, ct * x1 + st * y1, ct * x2 + st * y2
                    yr0, yr1, yr2 = ct * y0 - st * x0, ct * y1 - st * x1, ct * y2 - st * x2
                    o0, o1, o2 = o0 + di * z0 + ai * xn0, o1 + di * z1 + ai * xn1, o2 + di * z2 + ai * xn2
                    x0, x1, x2 = xn0, xn1, xn2
                    y0, y1, y2 = c * yr0 + s * z0, c * yr1 + s * z1, c * yr2 + s * z2
                    z0, z1, z2 = c * z0 - s * yr0, c * z1 - s * yr1, c * z2 - s * yr2
                    ax[i, 0], ax[i, 1], ax[i, 2], ax[i, 3], ax[i, 4], ax[i, 5] = x0, x1, x2, o0, o1, o2
                else:
                    ax[i, 0], ax[i, 1], ax[i, 2], ax[i, 3], ax[i, 4], ax[i, 5] = x0, x1, x2, o0, o1, o2
                    y10, y11, y12 = c * y0 + s * z0, c * y1 + s * z1, c * y2 + s * z2
                    z0, z1, z2 = c * z0 - s * y0, c * z1 - s * y1, c * z2 - s * y2
                    o0, o1, o2 = o0 + ai * x0, o1 + ai * x1, o2 + ai * x2
                    xn0, xn1, xn2 = ct * x0 + st * y10, ct * x1 + st * y11, ct * x2 + st * y12
                    y0, y1, y2 = ct * y10 - st * x0, ct * y11 - st * x1, ct * y12 - st * x2
                    x0, x1, x2 = xn0, xn1, xn2
                    o0, o1, o2 = o0 + di * z0, o1 + di * z1, o2 + di * z2
                    az[i, 0], az[i, 1], az[i, 2], az[i, 3], az[i, 4], az[i, 5] = z0, z1, z2, o0, o1, o2
            p0, p1, p2 = _store_pose(T, k, x0, x1, x2, y0, y1, y2, z0, z1, z2, o0, o1, o2, tool)
            if not jacobian:
                continue
            for i in range(dof):
                _length_column(J, k, i, ax[i, 0], ax[i, 1], ax[i, 2])
                _length_column(J, k, dof + i, az[i, 0], az[i, 1], az[i, 2])
                _angle_column(J, k, 2 * dof + i, ax[i, 0], ax[i, 1], ax[i, 2],
                              p0 - ax[i, 3], p1 - ax[i, 4], p2 - ax[i, 5])
                _angle_column(J, k, 3 * dof + i, az[i, 0], az[i, 1], az[i, 2],
                              p0 - az[i, 3], p1 - az[i, 4], p2 - az[i, 5])
    return -1


@njit
def _rpy_of(R, j, cr, sr, cp, sp, cy, sy):
    """R[j] = Rz(yaw) Ry(pitch) Rx(roll) from the cosines and sines of roll, pitch, yaw."""
    R[j, 0, 0] = cy * cp
    R[j, 0, 1] = cy * sp * sr - sy * cr
    R[j, 0, 2] = cy * sp * cr + sy * sr
    R[j, 1, 0] = sy * cp
    R[j, 1, 1] = sy * sp * sr + cy * cr
    R[j, 1, 2] = sy * sp * cr - cy * sr
    R[j, 2, 0] = -sp
    R[j, 2, 1] = cp * sr
    R[j, 2, 2] = cp * cr


@njit
def _rpy(R, j, roll, pitch, yaw):
    """R[j] = Rz(yaw) Ry(pitch) Rx(roll), rad."""
    _rpy_of(R, j, math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch), math.cos(yaw), math.sin(yaw))


@njit
def _origin_turn(rot, axes_in, j, rnom, ca, sa, cb, sb, cc, sc):
    """rot[j] = rnom[j] Rx(a) Ry(b) Rz(c) (the origin's nominal rotation, then its errors about its own x, y, z
    axes) from the cosines and sines of a, b, c; axes_in[j, 0], axes_in[j, 1] = the x and y error axes
    rnom[j] e_x, rnom[j] Rx(a) e_y in the frame before the origin rotation (the z one is the turned frame's z)."""
    e00, e01, e02 = cb * cc, -cb * sc, sb
    e10, e11, e12 = ca * sc + sa * sb * cc, ca * cc - sa * sb * sc, -sa * cb
    e20, e21, e22 = sa * sc - ca * sb * cc, sa * cc + ca * sb * sc, ca * cb
    for r in range(3):
        n0, n1, n2 = rnom[j, r, 0], rnom[j, r, 1], rnom[j, r, 2]
        rot[j, r, 0] = n0 * e00 + n1 * e10 + n2 * e20
        rot[j, r, 1] = n0 * e01 + n1 * e11 + n2 * e21
        rot[j, r, 2] = n0 * e02 + n1 * e12 + n2 * e22
        axes_in[j, 0, r] = n0
        axes_in[j, 1, r] = n1 * ca + n2 * sa


@njit
def urdf_chain(q, nominal, dx, revolute, fixed, origin_rpy, axes, tool, T, J, jacobian, writer):
    """URDF chain (see urdf.py): per joint j the fixed transform ``fixed[j]`` (4x4, m), the origin
    parameters x y z (m), the origin's nominal rotation ``origin_rpy[j]`` (roll, pitch, yaw, rad) turned by
    the parameters rx ry rz (rad, about its own axes in that order) and the offset (rad or m), about or
    along ``axes[j]``; J written by ``writer`` (a code of ``jacobian_writers.WRITERS``)."""
    bad = _first_nonfinite(q)
    if bad >= 0:
        return bad
    n, dof = q.shape
    per_pose = dx.shape[0] > 1
    rnom = np.empty((dof, 3, 3))     # nominal origin rotation of each joint
    rot = np.empty((dof, 3, 3))      # origin rotation of each joint, errors included
    axes_in = np.empty((dof, 2, 3))  # the rx and ry error axes before the origin rotation
    lines = np.empty((dof, 24))  # x, y, z axes before the origin rotation, rx, ry, joint axes; origin; rz axis
    plain = np.empty(dof, np.bool_)  # fixed[j] is exactly the identity
    along = np.empty(dof, np.int64)  # the joint axis is exactly +-x, +-y or +-z (0, 1, 2), else -1
    for j in range(dof):
        plain[j] = True
        for r in range(4):
            for c in range(4):
                if fixed[j, r, c] != (1.0 if r == c else 0.0):
                    plain[j] = False
        along[j] = -1
        for e in range(3):
            if abs(axes[j, e]) == 1.0 and axes[j, (e + 1) % 3] == 0.0 and axes[j, (e + 2) % 3] == 0.0:
                along[j] = e
        _rpy(rnom, j, origin_rpy[j, 0], origin_rpy[j, 1], origin_rpy[j, 2])
    width = 4 * dof if per_pose else dof   # angles per pose: joint angle (+ rx, ry, rz when per pose)
    ang = np.empty(BLOCK * width)
    sn = np.empty(BLOCK * width)
    cs = np.empty(BLOCK * width)
    # origin rotation of each joint: -2 none (roll = pitch = yaw = 0, no error), 0, 1, 2 about x, y or z alone
    # (cosine and sine in turn_cs), -1 any (``rot``, and always when the parameters vary per pose)
    turn = np.full(dof, -1, np.int64)
    turn_cs = np.empty((dof, 2))
    flat = J.reshape(-1)
    by_rows = jacobian and writer != 0
    stream = writer == 2
    if not per_pose:
        for j in range(dof):
            a, b, c = (_param(nominal, dx, 0, 7 * j + 3), _param(nominal, dx, 0, 7 * j + 4),
                       _param(nominal, dx, 0, 7 * j + 5))
            _origin_turn(rot, axes_in, j, rnom, math.cos(a), math.sin(a), math.cos(b), math.sin(b), math.cos(c),
                         math.sin(c))
            if a != 0.0 or b != 0.0 or c != 0.0:
                continue
            roll, pitch, yaw = origin_rpy[j, 0], origin_rpy[j, 1], origin_rpy[j, 2]
            if pitch == 0.0 and yaw == 0.0:
                turn[j] = -2 if roll == 0.0 else 0
                turn_cs[j, 0], turn_cs[j, 1] = math.cos(roll), math.sin(roll)
            elif roll == 0.0 and yaw == 0.0:
                turn[j] = 1
                turn_cs[j, 0], turn_cs[j, 1] = math.cos(pitch), math.sin(pitch)
            elif roll == 0.0 and pitch == 0.0:
                turn[j] = 2
                turn_cs[j, 0], turn_cs[j, 1] = math.cos(yaw), math.sin(yaw)
    for k0 in range(0, n, BLOCK):
        m = min(BLOCK, n - k0)
        for b in range(m):
            k = k0 + b
            row = k if per_pose else 0
            for j in range(dof):
                ang[b * width + j] = q[k, j] + _param(nominal, dx, row, 7 * j + 6)
                if per_pose:
                    for e in range(3):
                        ang[b * width + dof + 3 * j + e] = _param(nominal, dx, row, 7 * j + 3 + e)
        sincos(ang, sn, cs, m * width)
        for b in range(m):
            k = k0 + b
            row = k if per_pose else 0
            if per_pose:
                for j in range(dof):
                    e = b * width + dof + 3 * j
                    _origin_turn(rot, axes_in, j, rnom, cs[e], sn[e], cs[e + 1], sn[e + 1], cs[e + 2], sn[e + 2])
            _urdf_pose(q, nominal, dx, revolute, fixed, axes, tool, T, J, jacobian and not by_rows, k, row,
                       b * width, sn, cs, rot, axes_in, plain, turn, turn_cs, along, lines)
            if by_rows:
                _urdf_rows(flat, k, dof, lines, revolute, stream)
    if by_rows and stream:
        _fence()
    return -1


@njit
def _mul3(a00, a01, a02, a10, a11, a12, a20, a21, a22, B, j):
    """The 3x3 product A B[j], A given by its entries (row-major), B a stack of 3x3 (or 4x4) blocks."""
    return (a00 * B[j, 0, 0] + a01 * B[j, 1, 0] + a02 * B[j, 2, 0],
            a00 * B[j, 0, 1] + a01 * B[j, 1, 1] + a02 * B[j, 2, 1],
            a00 * B[j, 0, 2] + a01 * B[j, 1, 2] + a02 * B[j, 2, 2],
            a10 * B[j, 0, 0] + a11 * B[j, 1, 0] + a12 * B[j, 2, 0],
            a10 * B[j, 0, 1] + a11 * B[j, 1, 1] + a12 * B[j, 2, 1],
            a10 * B[j, 0, 2] + a11 * B[j, 1, 2] + a12 * B[j, 2, 2],
            a20 * B[j, 0, 0] + a21 * B[j, 1, 0] + a22 * B[j, 2, 0],
            a20 * B[j, 0, 1] + a21 * B[j, 1, 1] + a22 * B[j, 2, 1],
            a20 * B[j, 0, 2] + a21 * B[j, 1, 2] + a22 * B[j, 2, 2])


@njit
def _turn(a, c, s, g00, g01, g02, g10, g11, g12, g20, g21, g22):
    """G Rot(axis a, angle) for a base axis a = 0 (x), 1 (y), 2 (z) given the angle's cosine and sine: two
    columns of G turn in their plane. Entries row-major, as ``_mul3``."""
    if a == 0:
        return (g00, c * g01 + s * g02, c * g02 - s * g01,
                g10, c * g11 + s * g12, c * g12 - s * g11,
                g20, c * g21 + s * g22, c * g22 - s * g21)
    if a == 1:
        return (c * g00 - s * g02, g01, c * g02 + s * g00,
                c * g10 - s * g12, g11, c * g12 + s * g10,
                c * g20 - s * g22, g21, c * g22 + s * g20)
    return (c * g00 + s * g01, c * g01 - s * g00, g02,
            c * g10 + s * g11, c * g11 - s * g10, g12,
            c * g20 + s * g21, c * g21 - s * g20, g22)


@njit
def _urdf_pose(q, nominal, dx, revolute, fixed, axes, tool, T, J, columns, k, row, at, sn, cs,
               rot, axes_in, plain, turn, turn_cs, along, lines):
    """Pose k of urdf_chain: walks the chain, stores T[k], its lines (with the tool point minus the origins)
    and, when ``columns``, J[k]; joint angles' sin/cos at sn, cs[at:]."""
    dof = q.shape[1]
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
    o0, o1, o2 = 0.0, 0.0, 0.0
    for j in range(dof):
        # frame W = R F before the origin rotation, then the joint frame G = W rot at o + W xyz
        if plain[j]:
            w00, w01, w02, w10, w11, w12, w20, w21, w22 = r00, r01, r02, r10, r11, r12, r20, r21, r22
        else:
            o0 += r00 * fixed[j, 0, 3] + r01 * fixed[j, 1, 3] + r02 * fixed[j, 2, 3]
            o1 += r10 * fixed[j, 0, 3] + r11 * fixed[j, 1, 3] + r12 * fixed[j, 2, 3]
            o2 += r20 * fixed[j, 0, 3] + r21 * fixed[j, 1, 3] + r22 * fixed[j, 2, 3]
            w00, w01, w02, w10, w11, w12, w20, w21, w22 = _mul3(r00, r01, r02, r10, r11, r12, r20, r21, r22,
                                                                fixed, j)
        t = turn[j]
        if t == -1:
            g00, g01, g02, g10, g11, g12, g20, g21, g22 = _mul3(w00, w01, w02, w10, w11, w12, w20, w21, w22, rot, j)
        elif t == -2:
            g00, g01, g02, g10, g11, g12, g20, g21, g22 = w00, w01, w02, w10, w11, w12, w20, w21, w22
        else:
            g00, g01, g02, g10, g11, g12, g20, g21, g22 = _turn(t, turn_cs[j, 0], turn_cs[j, 1], w00, w01, w02,
                                                                w10, w11, w12, w20, w21, w22)
        sx, sy, sz = _param(nominal, dx, row, 7 * j), _param(nominal, dx, row, 7 * j + 1), \
            _param(nominal, dx, row, 7 * j + 2)
        o0 += w00 * sx + w01 * sy + w02 * sz
        o1 += w10 * sx + w11 * sy + w12 * sz
        o2 += w20 * sx + w21 * sy + w22 * sz
        u0, u1, u2 = axes[j, 0], axes[j, 1], axes[j, 2]
        a = along[j]
        if a == 0:
            v0, v1, v2 = g00 * u0, g10 * u0, g20 * u0
        elif a == 1:
            v0, v1, v2 = g01 * u1, g11 * u1, g21 * u1
        elif a == 2:
            v0, v1, v2 = g02 * u2, g12 * u2, g22 * u2
        else:
            v0 = g00 * u0 + g01 * u1 + g02 * u2
            v1 = g10 * u0 + g11 * u1 + g12 * u2
            v2 = g20 * u0 + g21 * u1 + g22 * u2
        x0, x1, x2 = axes_in[j, 0, 0], axes_in[j, 0, 1], axes_in[j, 0, 2]
        y0, y1, y2 = axes_in[j, 1, 0], axes_in[j, 1, 1], axes_in[j, 1, 2]
        lines[j, 0], lines[j, 1], lines[j, 2] = w00, w10, w20
        lines[j, 3], lines[j, 4], lines[j, 5] = w01, w11, w21
        lines[j, 6], lines[j, 7], lines[j, 8] = w02, w12, w22
        lines[j, 9] = w00 * x0 + w01 * x1 + w02 * x2
        lines[j, 10] = w10 * x0 + w11 * x1 + w12 * x2
        lines[j, 11] = w20 * x0 + w21 * x1 + w22 * x2
        lines[j, 12] = w00 * y0 + w01 * y1 + w02 * y2
        lines[j, 13] = w10 * y0 + w11 * y1 + w12 * y2
        lines[j, 14] = w20 * y0 + w21 * y1 + w22 * y2
        lines[j, 15], lines[j, 16], lines[j, 17] = v0, v1, v2
        lines[j, 18], lines[j, 19], lines[j, 20] = o0, o1, o2
        lines[j, 21], lines[j, 22], lines[j, 23] = g02, g12, g22
        if not revolute[j]:
            s = q[k, j] + _param(nominal, dx, row, 7 * j + 6)
            r00, r01, r02, r10, r11, r12, r20, r21, r22 = g00, g01, g02, g10, g11, g12, g20, g21, g22
            o0 += v0 * s
            o1 += v1 * s
            o2 += v2 * s
            continue
        c, s = cs[at + j], sn[at + j]
        if a >= 0:  # about +-x, +-y or +-z
            r00, r01, r02, r10, r11, r12, r20, r21, r22 = _turn(a, c, s * axes[j, a], g00, g01, g02, g10, g11, g12,
                                                                g20, g21, g22)
        else:
            # R = G Rot(u, q + offset) (Rodrigues)
            v = 1.0 - c
            q00, q01, q02 = c + u0 * u0 * v, u0 * u1 * v - u2 * s, u0 * u2 * v + u1 * s
            q10, q11, q12 = u1 * u0 * v + u2 * s, c + u1 * u1 * v, u1 * u2 * v - u0 * s
            q20, q21, q22 = u2 * u0 * v - u1 * s, u2 * u1 * v + u0 * s, c + u2 * u2 * v
            r00, r01, r02 = g00 * q00 + g01 * q10 + g02 * q20, g00 * q01 + g01 * q11 + g02 * q21, \
                g00 * q02 + g01 * q12 + g02 * q22
            r10, r11, r12 = g10 * q00 + g11 * q10 + g12 * q20, g10 * q01 + g11 * q11 + g12 * q21, \
                g10 * q02 + g11 * q12 + g12 * q22
            r20, r21, r22 = g20 * q00 + g21 * q10 + g22 * q20, g20 * q01 + g21 * q11 + g22 * q21, \
                g20 * q02 + g21 * q12 + g22 * q22
    p0, p1, p2 = _store_pose(T, k, r00, r10, r20, r01, r11, r21, r02, r12, r22, o0, o1, o2, tool)
    for j in range(dof):  # the origins become the tool point minus the origin
        lines[j, 18], lines[j, 19], lines[j, 20] = p0 - lines[j, 18], p1 - lines[j, 19], p2 - lines[j, 20]
    if not columns:
        return
    for j in range(dof):
        c = 7 * j
        a0, a1, a2 = lines[j, 18], lines[j, 19], lines[j, 20]
        _length_column(J, k, c, lines[j, 0], lines[j, 1], lines[j, 2])
        _length_column(J, k, c + 1, lines[j, 3], lines[j, 4], lines[j, 5])
        _length_column(J, k, c + 2, lines[j, 6], lines[j, 7], lines[j, 8])
        _angle_column(J, k, c + 3, lines[j, 9], lines[j, 10], lines[j, 11], a0, a1, a2)
        _angle_column(J, k, c + 4, lines[j, 12], lines[j, 13], lines[j, 14], a0, a1, a2)
        _angle_column(J, k, c + 5, lines[j, 21], lines[j, 22], lines[j, 23], a0, a1, a2)
        if revolute[j]:
            _angle_column(J, k, c + 6, lines[j, 15], lines[j, 16], lines[j, 17], a0, a1, a2)
        else:
            _length_column(J, k, c + 6, lines[j, 15], lines[j, 16], lines[j, 17])


@njit
def _put(flat, i, value, stream):
    """flat[i] = value, as a streaming store when ``stream``."""
    if stream:
        _stream(flat, i, value)
    else:
        flat[i] = value


@njit
def _urdf_rows(flat, k, dof, lines, revolute, stream):
    """J[k] of urdf_chain row by row in memory order (``flat``: J flattened), streaming stores when
    ``stream``, from the lines of ``_urdf_pose``; called by urdf_chain itself (see the module docstring:
    called from ``_urdf_pose``, a reference count came between the poses' stores, 1.5x slower)."""
    i = k * 42 * dof
    for r in range(3):
        r1, r2 = (r + 1) % 3, (r + 2) % 3
        for j in range(dof):
            a1, a2 = lines[j, 18 + r1], lines[j, 18 + r2]
            _put(flat, i, lines[j, r], stream)
            _put(flat, i + 1, lines[j, 3 + r], stream)
            _put(flat, i + 2, lines[j, 6 + r], stream)
            _put(flat, i + 3, lines[j, 9 + r1] * a2 - lines[j, 9 + r2] * a1, stream)
            _put(flat, i + 4, lines[j, 12 + r1] * a2 - lines[j, 12 + r2] * a1, stream)
            _put(flat, i + 5, lines[j, 21 + r1] * a2 - lines[j, 21 + r2] * a1, stream)
            if revolute[j]:
                _put(flat, i + 6, lines[j, 15 + r1] * a2 - lines[j, 15 + r2] * a1, stream)
            else:
                _put(flat, i + 6, lines[j, 15 + r], stream)
            i += 7
    for r in range(3):
        for j in range(dof):
            _put(flat, i, 0.0, stream)
            _put(flat, i + 1, 0.0, stream)
            _put(flat, i + 2, 0.0, stream)
            _put(flat, i + 3, lines[j, 9 + r], stream)
            _put(flat, i + 4, lines[j, 12 + r], stream)
            _put(flat, i + 5, lines[j, 21 + r], stream)
            _put(flat, i + 6, lines[j, 15 + r] if revolute[j] else 0.0, stream)
            i += 7




@njit
def _rot(out, a0, a1, a2, angle):
    """out (3, 3) = the rotation by ``angle`` (rad) about the unit axis (a0, a1, a2) (Rodrigues, as numpy's)."""
    c, s = math.cos(angle), math.sin(angle)
    v = 2.0 * math.sin(angle / 2.0) ** 2
    out[0, 0], out[0, 1], out[0, 2] = c + a0 * a0 * v, a0 * a1 * v - a2 * s, a0 * a2 * v + a1 * s
    out[1, 0], out[1, 1], out[1, 2] = a1 * a0 * v + a2 * s, c + a1 * a1 * v, a1 * a2 * v - a0 * s
    out[2, 0], out[2, 1], out[2, 2] = a2 * a0 * v - a1 * s, a2 * a1 * v + a0 * s, c + a2 * a2 * v


@njit
def _mm(out, A, B):
    """out (3, 3) = A[:3, :3] @ B[:3, :3] (out distinct from A and B)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]


@njit
def _column(cols, c, kind, sign, R, axis_col, point):
    """Parameter column c: kind 0 a shift along R[:, axis_col], 1 a turn about it through ``point``; ``sign``."""
    cols[c, 0], cols[c, 1] = kind, sign
    for i in range(3):
        cols[c, 2 + i] = R[i, axis_col]
        cols[c, 5 + i] = point[i]


@njit
def urdf_either_way(q, nominal, dx, revolute, reversed_, fixed, origin_rpy, axes, start, tool, T, J, jacobian):
    """URDF chain with joints traversed from child to parent (``reversed_``): the element of such a joint is
    ``M(q + offset)^-1 O^-1 fixed^-1`` (``fixed`` given inverted), turning by -rz, -ry, -rx about its joint frame's
    axes and shifting by -xyz along its parent's; the others as ``urdf_chain`` (``start`` before the first
    element). The numpy reference is ``URDFChain._fk_and_jacobian_either_way``; J column by column."""
    bad = _first_nonfinite(q)
    if bad >= 0:
        return bad
    n, dof = q.shape
    per_pose = dx.shape[0] > 1
    p = 7 * dof
    R = np.empty((3, 3))
    W = np.empty((3, 3))
    N = np.empty((3, 3))
    X = np.empty((3, 3))
    Y = np.empty((3, 3))
    Z = np.empty((3, 3))
    G = np.empty((3, 3))
    E = np.empty((3, 3))
    rpy = np.empty((dof, 3, 3))
    rpy_t = np.empty((dof, 3, 3))
    for j in range(dof):
        _rpy(rpy, j, origin_rpy[j, 0], origin_rpy[j, 1], origin_rpy[j, 2])
        for a in range(3):
            for b in range(3):
                rpy_t[j, a, b] = rpy[j, b, a]
    o = np.empty(3)
    oj = np.empty(3)
    w = np.empty(3)
    cols = np.empty((p, 8))   # kind, sign, direction (3), point (3)
    for k in range(n):
        row = k if per_pose else 0
        for a in range(3):
            o[a] = start[a, 3]
            for b in range(3):
                R[a, b] = start[a, b]
        for j in range(dof):
            c0 = 7 * j
            x, y, z = _param(nominal, dx, row, c0), _param(nominal, dx, row, c0 + 1), _param(nominal, dx, row, c0 + 2)
            rx, ry, rz = (_param(nominal, dx, row, c0 + 3), _param(nominal, dx, row, c0 + 4),
                          _param(nominal, dx, row, c0 + 5))
            theta = q[k, j] + _param(nominal, dx, row, c0 + 6)
            a0, a1, a2 = axes[j, 0], axes[j, 1], axes[j, 2]
            F = fixed[j]
            if not reversed_[j]:
                _mm(W, R, F)                                  # RW
                for a in range(3):
                    oj[a] = o[a] + R[a, 0] * F[0, 3] + R[a, 1] * F[1, 3] + R[a, 2] * F[2, 3]
                _mm(N, W, rpy[j])                             # RN
                _rot(E, 1.0, 0.0, 0.0, rx)
                _mm(X, N, E)                                  # RX
                _rot(E, 0.0, 1.0, 0.0, ry)
                _mm(Y, X, E)
                _rot(E, 0.0, 0.0, 1.0, rz)
                _mm(Z, Y, E)                                  # RJ
                for a in range(3):
                    oj[a] += W[a, 0] * x + W[a, 1] * y + W[a, 2] * z
                    w[a] = Z[a, 0] * a0 + Z[a, 1] * a1 + Z[a, 2] * a2
                for i in range(3):
                    _column(cols, c0 + i, 0, 1.0, W, i, oj)
                _column(cols, c0 + 3, 1, 1.0, N, 0, oj)
                _column(cols, c0 + 4, 1, 1.0, X, 1, oj)
                _column(cols, c0 + 5, 1, 1.0, Z, 2, oj)
                cols[c0 + 6, 0], cols[c0 + 6, 1] = (1 if revolute[j] else 0), 1.0
                for a in range(3):
                    cols[c0 + 6, 2 + a], cols[c0 + 6, 5 + a] = w[a], oj[a]
                if revolute[j]:
                    _rot(E, a0, a1, a2, theta)
                    _mm(R, Z, E)
                    for a in range(3):
                        o[a] = oj[a]
                else:
                    for a in range(3):
                        o[a] = oj[a] + w[a] * theta
                        for b in range(3):
                            R[a, b] = Z[a, b]
            else:
                for a in range(3):
                    w[a] = R[a, 0] * a0 + R[a, 1] * a1 + R[a, 2] * a2
                cols[c0 + 6, 0], cols[c0 + 6, 1] = (1 if revolute[j] else 0), -1.0
                for a in range(3):
                    cols[c0 + 6, 2 + a], cols[c0 + 6, 5 + a] = w[a], o[a]
                if revolute[j]:
                    _rot(E, a0, a1, a2, -theta)
                    _mm(G, R, E)                              # RG, at oG = o
                else:
                    for a in range(3):
                        o[a] -= w[a] * theta
                        for b in range(3):
                            G[a, b] = R[a, b]
                _rot(E, 0.0, 0.0, 1.0, -rz)
                _mm(X, G, E)                                  # R1
                _rot(E, 0.0, 1.0, 0.0, -ry)
                _mm(Y, X, E)                                  # R2
                _rot(E, 1.0, 0.0, 0.0, -rx)
                _mm(Z, Y, E)                                  # R3
                _mm(N, Z, rpy_t[j])                           # R4
                _column(cols, c0 + 3, 1, -1.0, Y, 0, o)
                _column(cols, c0 + 4, 1, -1.0, X, 1, o)
                _column(cols, c0 + 5, 1, -1.0, G, 2, o)
                for a in range(3):
                    oj[a] = o[a] - (N[a, 0] * x + N[a, 1] * y + N[a, 2] * z)   # o4
                for i in range(3):
                    _column(cols, c0 + i, 0, -1.0, N, i, oj)
                _mm(R, N, F)
                for a in range(3):
                    o[a] = oj[a] + N[a, 0] * F[0, 3] + N[a, 1] * F[1, 3] + N[a, 2] * F[2, 3]
        _mm(E, R, tool)
        for a in range(3):
            oj[a] = o[a] + R[a, 0] * tool[0, 3] + R[a, 1] * tool[1, 3] + R[a, 2] * tool[2, 3]
            for b in range(3):
                T[k, a, b] = E[a, b]
            T[k, a, 3] = oj[a]
            T[k, 3, a] = 0.0
        T[k, 3, 3] = 1.0
        if jacobian:
            for c in range(p):
                sign = cols[c, 1]
                u0, u1, u2 = cols[c, 2], cols[c, 3], cols[c, 4]
                if cols[c, 0] == 0.0:
                    J[k, 0, c], J[k, 1, c], J[k, 2, c] = sign * u0, sign * u1, sign * u2
                    J[k, 3, c], J[k, 4, c], J[k, 5, c] = 0.0, 0.0, 0.0
                else:
                    r0, r1, r2 = oj[0] - cols[c, 5], oj[1] - cols[c, 6], oj[2] - cols[c, 7]
                    J[k, 0, c] = sign * (u1 * r2 - u2 * r1)
                    J[k, 1, c] = sign * (u2 * r0 - u0 * r2)
                    J[k, 2, c] = sign * (u0 * r1 - u1 * r0)
                    J[k, 3, c], J[k, 4, c], J[k, 5, c] = sign * u0, sign * u1, sign * u2
    return -1


def warm_up(which=("dh", "urdf")):
    """Compile, or load from the cache, dh_chain and/or urdf_chain in the signature the models call."""
    q = np.zeros((1, 1))
    T = np.empty((1, 4, 4))
    eye = np.eye(4)
    revolute = np.ones(1, dtype=np.bool_)
    if "dh" in which:
        dh_chain(q, np.zeros(4), NO_DX, revolute, True, eye, eye, T, np.empty((1, 6, 4)), True)
    if "urdf" in which:
        urdf_chain(q, np.zeros(7), NO_DX, revolute, eye.reshape(1, 4, 4).copy(), np.zeros((1, 3)),
                   np.array([[0.0, 0.0, 1.0]]), eye, T, np.empty((1, 6, 7)), True, 0)
        urdf_either_way(q, np.zeros(7), NO_DX, revolute, revolute.copy(), eye.reshape(1, 4, 4).copy(), np.zeros((1, 3)),
                        np.array([[0.0, 0.0, 1.0]]), eye, eye, T, np.empty((1, 6, 7)), True)

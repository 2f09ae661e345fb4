"""Compiled (numba) forward kinematics and error transfer G of the 3-PUPS platform (``pups.py``).

``pups.PUPS3``'s numpy code (``_solve``, ``_error_transfer``) is the reference. ``pups_solve`` runs the same
algorithm pose by pose in one compiled loop: the same start (the platform shrunk to a point, Gauss-Newton,
then R = I), the same damped Newton steps on the six closure equations (normal equations with the same
damping, up to 12 step halvings, the same thresholds), the same retries from the yaw starts, the same
passive angles and G = J1^-1 J2. The differences, all below the stopping thresholds:

- the start's Gauss-Newton stops pose by pose (the numpy code stops when the slowest pose of the batch has,
  so that its result for one pose depends, by less than the 1e-10 m stopping step, on the others);
- J1 (orientation columns scaled by 1/c) is inverted once and G = J1^-1 J2 formed from the two non-zero
  rows of each column of J2, rather than solved column by column.

The tests check T and G against the numpy code (``test/core/models/test_pups.py``).

The singularity check, cond(J1 scaled) > cond_limit, is left to the caller: the kernel returns the
Frobenius condition number ||J1s||_F ||J1s^-1||_F, never below the 2-norm one numpy computes (and at most 6
times it), and writes J1s only for the poses where it is above ``flag``, so that only those need an SVD.

Arguments: ``q`` (n, 9) joints; ``dx`` (m, 27) parameter errors (m = 0: none, 1: shared, n: one a pose);
``RA`` (3, 3, 3) slider frames; ``c_local`` (3, 3) platform sphere centres; ``c`` the platform radius;
``yaw_starts`` (k, 3, 3) the retry rotations; ``e1``, ``e2`` the U-joint axes (0 x, 1 y); ``flag`` the
Frobenius condition number above which J1s is written; outputs ``T`` (n, 4, 4), ``G`` (n, 6, 27, ignored
unless ``jacobian``), ``theta`` (n, 3), ``J1s`` (n, 6, 6, written where ``kappa`` > ``flag``), ``kappa`` (n,),
``status`` (n,) int8: 0 assembled, 1 not closed, 2 only a turned-over assembly found (``kappa`` 0 and G
not written unless 0). Returns the number of poses with a status other than 0 or a ``kappa`` above ``flag``.

Compiled with numpy's floating-point error model (x / 0 is inf or NaN, as in the numpy code, not
ZeroDivisionError: joints far outside the mechanism's range give such poses, which fail with their reason)
and cached on disk like every kernel (``jit.njit``).
"""
from __future__ import annotations

import math
import time

import numpy as np

from .jit import NO_DX, NO_J, njit

CLOSED = 1e-10  # residual norm of an assembled pose (pups._solve)
NEWTON_TOL = 1e-14  # Newton stops below this residual norm (pups._newton)
NEWTON_STEPS = 60
HALVINGS = 12
START_STEPS = 30
START_TOL = 1e-10

# Helpers are not inlined (numba IR inlining made the cold compile about 4 s longer, not the kernel faster),
# and _lu_solve takes its sizes from the arrays' shapes, not literals: one compiled specialisation, not three.
_njit = njit(error_model="numpy", inline="never")


@_njit
def _axis_rotation(axis, angle, out):
    """out (3, 3) = rotation by ``angle`` about base axis ``axis`` (geometry.axis_angle_matrix's formulas)."""
    c, s = math.cos(angle), math.sin(angle)
    h = math.sin(angle / 2.0)
    v = 2.0 * h * h
    x = 1.0 if axis == 0 else 0.0
    y = 1.0 if axis == 1 else 0.0
    z = 1.0 if axis == 2 else 0.0
    out[0, 0], out[0, 1], out[0, 2] = c + x * x * v, x * y * v - z * s, x * z * v + y * s
    out[1, 0], out[1, 1], out[1, 2] = y * x * v + z * s, c + y * y * v, y * z * v - x * s
    out[2, 0], out[2, 1], out[2, 2] = z * x * v - y * s, z * y * v + x * s, c + z * z * v


@_njit
def _lu_solve(A, X, n, m):
    """X[:n, :m] = A[:n, :n]^-1 X by Gaussian elimination with partial pivoting (A overwritten); X NaN when a
    pivot is exactly zero (LAPACK's solve then raises, and the numpy code gives the pose NaN)."""
    for col in range(n):
        piv, best = col, abs(A[col, col])
        for r in range(col + 1, n):
            a = abs(A[r, col])
            if a > best:
                piv, best = r, a
        if best == 0.0:
            for i in range(n):
                for j in range(m):
                    X[i, j] = np.nan
            return
        if piv != col:
            for j in range(n):
                A[col, j], A[piv, j] = A[piv, j], A[col, j]
            for j in range(m):
                X[col, j], X[piv, j] = X[piv, j], X[col, j]
        inv = 1.0 / A[col, col]
        for r in range(col + 1, n):
            fac = A[r, col] * inv
            for j in range(col + 1, n):
                A[r, j] -= fac * A[col, j]
            for j in range(m):
                X[r, j] -= fac * X[col, j]
    for col in range(n - 1, -1, -1):
        inv = 1.0 / A[col, col]
        for j in range(m):
            acc = X[col, j]
            for r in range(col + 1, n):
                acc -= A[col, r] * X[r, j]
            X[col, j] = acc * inv


@_njit
def _residual(p, R, c_local, centre, kv, rho, f, d):
    """f (6,) closure residuals, limb by limb (sphere, circle plane), and d (3, 3) = C_i - O_i; returns |f|."""
    acc = 0.0
    for i in range(3):
        dd, kd = 0.0, 0.0
        for j in range(3):
            C = p[j] + (R[j, 0] * c_local[i, 0] + R[j, 1] * c_local[i, 1] + R[j, 2] * c_local[i, 2])
            dj = C - centre[i, j]
            d[i, j] = dj
            dd += dj * dj
            kd += kv[i, j] * dj
        f[2 * i] = (dd - rho[i] * rho[i]) / (2.0 * rho[i])
        f[2 * i + 1] = kd
        acc += f[2 * i] * f[2 * i] + f[2 * i + 1] * f[2 * i + 1]
    return math.sqrt(acc)


@_njit
def _rows(R, c_local, dirs, J):
    """J (6, 6) rows [n^T, (R c_i x n)^T] for the directions dirs (6, 3), limb by limb."""
    for i in range(3):
        r0 = R[0, 0] * c_local[i, 0] + R[0, 1] * c_local[i, 1] + R[0, 2] * c_local[i, 2]
        r1 = R[1, 0] * c_local[i, 0] + R[1, 1] * c_local[i, 1] + R[1, 2] * c_local[i, 2]
        r2 = R[2, 0] * c_local[i, 0] + R[2, 1] * c_local[i, 1] + R[2, 2] * c_local[i, 2]
        for row in range(2 * i, 2 * i + 2):
            n0, n1, n2 = dirs[row, 0], dirs[row, 1], dirs[row, 2]
            J[row, 0], J[row, 1], J[row, 2] = n0, n1, n2
            J[row, 3] = r1 * n2 - r2 * n1
            J[row, 4] = r2 * n0 - r0 * n2
            J[row, 5] = r0 * n1 - r1 * n0


@_njit
def _exp_times(w0, w1, w2, R, out):
    """out = exp([w]x) R (geometry.exp_so3's formulas)."""
    th = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    div = th if th > 0 else 1.0
    x, y, z = w0 / div, w1 / div, w2 / div
    c, s = math.cos(th), math.sin(th)
    h = math.sin(th / 2.0)
    v = 2.0 * h * h
    e00, e01, e02 = c + x * x * v, x * y * v - z * s, x * z * v + y * s
    e10, e11, e12 = y * x * v + z * s, c + y * y * v, y * z * v - x * s
    e20, e21, e22 = z * x * v - y * s, z * y * v + x * s, c + z * z * v
    for j in range(3):
        r0, r1, r2 = R[0, j], R[1, j], R[2, j]
        out[0, j] = e00 * r0 + e01 * r1 + e02 * r2
        out[1, j] = e10 * r0 + e11 * r1 + e12 * r2
        out[2, j] = e20 * r0 + e21 * r1 + e22 * r2


@_njit
def pups_solve(q, dx, RA, c_local, c, yaw_starts, e1, e2, flag, jacobian, T, G, theta, J1s, kappa, status):
    """Poses, passive angles, the Frobenius condition number of J1 (scaled) and G of joints q (see the
    module docstring)."""
    n = q.shape[0]
    Rot = np.empty((3, 3))
    M = np.empty((3, 3, 3))
    hub = np.empty((3, 3))
    centre = np.empty((3, 3))
    kv = np.empty((3, 3))
    L = np.empty((3, 3))
    rho = np.empty(3)
    p0 = np.empty(3)
    A3 = np.empty((3, 3))
    b3 = np.empty((3, 1))
    J3 = np.empty((6, 3))
    f3 = np.empty(6)
    p, pt, pb = np.empty(3), np.empty(3), np.empty(3)
    R, Rt, Rb = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    d, dt, db = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    f, ft = np.empty(6), np.empty(6)
    dirs = np.empty((6, 3))
    J = np.empty((6, 6))
    A = np.empty((6, 6))
    b = np.empty((6, 1))
    X = np.empty((6, 6))
    J2 = np.empty((2, 9))
    shared = dx.shape[0] == 1
    errors = dx.shape[0] > 0
    attention = 0
    for k in range(n):
        row = 0 if shared else k
        # ---- limb geometry (pups._limbs)
        for i in range(3):
            a, psi, length = q[k, i], q[k, 3 + i], q[k, 6 + i]
            for j in range(3):
                hub[i, j] = -a * RA[i, j, 0]
                L[i, j] = 0.0
            if errors:
                for j in range(3):
                    hub[i, j] += dx[row, 9 * i + j]
                for j in range(3):
                    hub[i, j] += (RA[i, j, 0] * dx[row, 9 * i + 3] + RA[i, j, 1] * dx[row, 9 * i + 4]
                                  + RA[i, j, 2] * dx[row, 9 * i + 5])
                for j in range(3):
                    L[i, j] = dx[row, 9 * i + 6 + j]
            L[i, 2] += length
            _axis_rotation(e1, psi, Rot)
            for j in range(3):
                for e in range(3):
                    M[i, j, e] = RA[i, j, 0] * Rot[0, e] + RA[i, j, 1] * Rot[1, e] + RA[i, j, 2] * Rot[2, e]
            along = L[i, e2]
            acc = 0.0
            for j in range(3):
                kv[i, j] = M[i, j, e2]
                centre[i, j] = hub[i, j] + kv[i, j] * along
                if j != e2:
                    acc += L[i, j] * L[i, j]
            rho[i] = math.sqrt(acc)
        # ---- start (pups._start): the platform shrunk to a point, Gauss-Newton, stopped pose by pose
        mean_rho = ((rho[0] + rho[1]) + rho[2]) / 3.0
        for j in range(3):
            p0[j] = ((centre[0, j] + centre[1, j]) + centre[2, j]) / 3.0 + (1.0 if j == 2 else 0.0) * mean_rho
        for _ in range(START_STEPS):
            for i in range(3):
                dd, kd = 0.0, 0.0
                for j in range(3):
                    dj = p0[j] - centre[i, j]
                    dd += dj * dj
                    kd += kv[i, j] * dj
                    J3[i, j] = dj / rho[i]
                    J3[3 + i, j] = kv[i, j]
                f3[i] = (dd - rho[i] * rho[i]) / (2 * rho[i])
                f3[3 + i] = kd
            for u in range(3):
                acc = 0.0
                for r in range(6):
                    acc += J3[r, u] * f3[r]
                b3[u, 0] = acc
                for e in range(3):
                    acc = 0.0
                    for r in range(6):
                        acc += J3[r, u] * J3[r, e]
                    A3[u, e] = acc
                A3[u, u] += 1e-12
            _lu_solve(A3, b3, A3.shape[0], b3.shape[1])
            big = 0.0
            for j in range(3):
                p0[j] -= b3[j, 0]
                big = max(big, abs(b3[j, 0]))
            if big < START_TOL or not big == big:
                break
        # ---- Newton from R = I, then from the yaw starts while no upright assembly is found (pups._solve)
        best = np.nan
        for attempt in range(1 + yaw_starts.shape[0]):
            if attempt > 0 and not (best > CLOSED or Rb[2, 2] <= 0.0):
                break
            for j in range(3):
                p[j] = p0[j]
                for e in range(3):
                    R[j, e] = (1.0 if j == e else 0.0) if attempt == 0 else yaw_starts[attempt - 1, j, e]
            norm = _residual(p, R, c_local, centre, kv, rho, f, d)
            for _ in range(NEWTON_STEPS):
                if not norm > NEWTON_TOL:
                    break
                # one damped step: (J^T J + 1e-14 I) s = J^T f, rows of J along d_i / rho_i and k_i
                for i in range(3):
                    for j in range(3):
                        dirs[2 * i, j] = d[i, j] / rho[i]
                        dirs[2 * i + 1, j] = kv[i, j]
                _rows(R, c_local, dirs, J)
                for u in range(6):
                    acc = 0.0
                    for r in range(6):
                        acc += J[r, u] * f[r]
                    b[u, 0] = acc
                    for e in range(u, 6):
                        acc = 0.0
                        for r in range(6):
                            acc += J[r, u] * J[r, e]
                        A[u, e] = acc
                        A[e, u] = acc
                    A[u, u] += 1e-14
                _lu_solve(A, b, A.shape[0], b.shape[1])
                t = 1.0
                improved = False
                for _ls in range(HALVINGS):
                    for j in range(3):
                        pt[j] = p[j] - t * b[j, 0]
                    _exp_times(-t * b[3, 0], -t * b[4, 0], -t * b[5, 0], R, Rt)
                    nt = _residual(pt, Rt, c_local, centre, kv, rho, ft, dt)
                    if nt < norm:
                        norm = nt
                        for j in range(3):
                            p[j] = pt[j]
                            for e in range(3):
                                R[j, e] = Rt[j, e]
                                d[j, e] = dt[j, e]
                        for j in range(6):
                            f[j] = ft[j]
                        improved = True
                        break
                    t *= 0.5
                if not improved:
                    break
            if attempt == 0 or (norm <= CLOSED and R[2, 2] > 0.0):
                best = norm
                for j in range(3):
                    pb[j] = p[j]
                    for e in range(3):
                        Rb[j, e] = R[j, e]
                        db[j, e] = d[j, e]
        st = 1 if not best <= CLOSED else (0 if Rb[2, 2] > 0.0 else 2)
        status[k] = st
        for i in range(3):
            for j in range(3):
                T[k, i, j] = Rb[i, j]
            T[k, i, 3] = pb[i]
            T[k, 3, i] = 0.0
        T[k, 3, 3] = 1.0
        # ---- passive angles: theta_i = atan2(e2 . (Lperp x v), Lperp . v), v = M_i^T d_i
        for i in range(3):
            v0 = M[i, 0, 0] * db[i, 0] + M[i, 1, 0] * db[i, 1] + M[i, 2, 0] * db[i, 2]
            v1 = M[i, 0, 1] * db[i, 0] + M[i, 1, 1] * db[i, 1] + M[i, 2, 1] * db[i, 2]
            v2 = M[i, 0, 2] * db[i, 0] + M[i, 1, 2] * db[i, 1] + M[i, 2, 2] * db[i, 2]
            l0 = L[i, 0] if e2 != 0 else 0.0
            l1 = L[i, 1] if e2 != 1 else 0.0
            l2 = L[i, 2]
            cross = (l2 * v0 - l0 * v2) if e2 == 1 else (l1 * v2 - l2 * v1)
            theta[k, i] = math.atan2(cross, (l0 * v0 + l1 * v1) + l2 * v2)
        if st != 0:
            kappa[k] = 0.0
            attention += 1
            continue
        # ---- J1 with unit directions, its orientation columns scaled by 1/c; its inverse; kappa
        for i in range(3):
            nd = math.sqrt(db[i, 0] * db[i, 0] + db[i, 1] * db[i, 1] + db[i, 2] * db[i, 2])
            for j in range(3):
                dirs[2 * i, j] = db[i, j] / nd
                dirs[2 * i + 1, j] = kv[i, j]
        _rows(Rb, c_local, dirs, J)
        fro = 0.0
        for r in range(6):
            for j in range(3, 6):
                J[r, j] /= c
            for j in range(6):
                A[r, j] = J[r, j]
                X[r, j] = 1.0 if r == j else 0.0
                fro += J[r, j] * J[r, j]
        _lu_solve(A, X, A.shape[0], X.shape[1])
        inv = 0.0
        for r in range(6):
            for j in range(6):
                inv += X[r, j] * X[r, j]
        kap = math.sqrt(fro * inv)
        kappa[k] = kap
        if not kap <= flag:
            attention += 1
            for r in range(6):
                for j in range(6):
                    J1s[k, r, j] = J[r, j]
        if not jacobian:
            continue
        # ---- G = J1^-1 J2 (pups._error_transfer); J2's rows 2i, 2i + 1 are non-zero in limb i's columns only:
        # D, D R_Ai, D R_Ai R_Bi (D the two unit directions), and J1^-1 = diag(1, 1, 1, 1/c, 1/c, 1/c) J1s^-1
        for i in range(3):
            _axis_rotation(e2, theta[k, i], Rot)
            for h in range(2):
                n0, n1, n2 = dirs[2 * i + h, 0], dirs[2 * i + h, 1], dirs[2 * i + h, 2]
                J2[h, 0], J2[h, 1], J2[h, 2] = n0, n1, n2
                for e in range(3):
                    J2[h, 3 + e] = n0 * RA[i, 0, e] + n1 * RA[i, 1, e] + n2 * RA[i, 2, e]
                m0 = n0 * M[i, 0, 0] + n1 * M[i, 1, 0] + n2 * M[i, 2, 0]
                m1 = n0 * M[i, 0, 1] + n1 * M[i, 1, 1] + n2 * M[i, 2, 1]
                m2 = n0 * M[i, 0, 2] + n1 * M[i, 1, 2] + n2 * M[i, 2, 2]
                for e in range(3):
                    J2[h, 6 + e] = m0 * Rot[0, e] + m1 * Rot[1, e] + m2 * Rot[2, e]
            for r in range(6):
                g0, g1 = X[r, 2 * i], X[r, 2 * i + 1]
                if r >= 3:
                    g0 /= c
                    g1 /= c
                for e in range(9):
                    G[k, r, 9 * i + e] = g0 * J2[0, e] + g1 * J2[1, e]
    return attention


def solve(model, q, dx, jacobian):
    """``pups_solve`` for a PUPS3 ``model`` on checked joints q (n, 9) and dx (None, (27,) or (n, 27)); returns
    (T, G or None, theta, J1s, kappa, status, attention), J1s written where kappa > cond_limit / 2, attention the
    number of poses that failed or were so written (0: every pose assembled, none near a singularity)."""
    n = q.shape[0]
    if not (q.flags.c_contiguous and q.dtype == np.float64):
        q = np.ascontiguousarray(q, dtype=np.float64)
    dx = NO_DX if dx is None else np.ascontiguousarray(np.reshape(dx, (-1, 27)), dtype=np.float64)
    T = np.empty((n, 4, 4))
    G = np.empty((n, 6, 27)) if jacobian else NO_J
    theta = np.empty((n, 3))
    J1s = np.empty((n, 6, 6))
    kappa = np.empty(n)
    status = np.empty(n, dtype=np.int8)
    RA, c_local, c, yaw_starts, e1, e2 = model._kernel_constants
    attention = pups_solve(q, dx, RA, c_local, c, yaw_starts, e1, e2, 0.5 * model.cond_limit, bool(jacobian), T, G,
                           theta, J1s, kappa, status)
    return T, (G if jacobian else None), theta, J1s, kappa, status, attention


def warm_up() -> float:
    """Compile, or load from the cache, ``pups_solve`` in the signature ``solve`` calls; returns seconds."""
    t0 = time.perf_counter()
    RA = np.ascontiguousarray(np.broadcast_to(np.eye(3), (3, 3, 3)))
    pups_solve(np.zeros((1, 9)), NO_DX, RA, np.eye(3), 1.0, np.empty((0, 3, 3)), 0, 1, 1.0, True,
               np.empty((1, 4, 4)), np.empty((1, 6, 27)), np.empty((1, 3)), np.empty((1, 6, 6)), np.empty(1),
               np.empty(1, np.int8))
    return time.perf_counter() - t0

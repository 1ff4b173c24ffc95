"""The shield's compiled numeric kernels (numba, no fastmath): the stopping sweeps' profiles,
the lidar scan's points with rebuilt corners, and the outline-against-points tests. Each
computes, in the same order, what the array expressions it replaced computed, so the shield's
answers are the same bit for bit (:mod:`bulletnav.control.shield` uses them)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def sweep_profile(v, w, v_now, w_now, tail, dt, decel, half_base, out, tighten=False):  # pragma: no cover  (compiled)
    """Times (C, K), mid-interval headings (C, K-1) and distances travelled per interval (C, K-1)
    of the stopping sweeps of commands (``v``, ``w``: (C,)), yaws written into ``out[:, :, 2]``
    (see :meth:`~bulletnav.control.shield.Shield.sweep`; ``w_now`` NaN: no yaw-rate transient). Each value is computed by
    the formula, and in the order, of the array expressions it replaced (numpy's ``maximum`` /
    ``minimum`` and sequential ``cumsum``), so the sweeps are the same bit for bit; the headings'
    cosines and sines stay numpy's. With ``tighten`` a moving command keeps its yaw rate while it
    brakes (the arc tightens to a spiral) instead of keeping its curvature, and once stopped its
    turn spins down at the rim deceleration, as a turn in place does."""
    n_cmd, n = out.shape[0], out.shape[1]
    t = np.zeros((n_cmd, n))
    mid = np.zeros((n_cmd, n - 1))
    ds = np.zeros((n_cmd, n - 1))
    after = np.zeros(n)
    rate = np.zeros(n)
    travelled = np.zeros(n)
    for c in range(n_cmd):
        vc, wc = v[c], w[c]
        drive = vc > 0
        back = vc < 0  # backing up (an env with TaskConfig.min_speed < 0): the same sweep, mirrored
        if drive:
            v1 = v_now if v_now >= vc else vc
        elif back:
            v1 = -v_now if v_now <= vc else -vc  # the speed backwards: the larger of the two
        else:
            v1 = v_now if v_now >= 0.0 else 0.0
        stop = v1 / decel
        spin = 0.0 if drive or back else abs(wc) * half_base / decel
        longest = stop if stop >= spin else spin
        if tighten and (drive or back):  # the yaw rate holds to the stop, then spins down at the rim deceleration
            spin = abs(wc) * half_base / decel
            longest = stop + spin
        after[0] = 0.0
        after[1] = 0.0
        for k in range(2, n):
            after[k] = tail[k - 2] * longest
        for k in range(n):
            t[c, k] = after[k] + dt
        t[c, 0] = 0.0
        for k in range(n):
            braking = after[k] if after[k] <= stop else stop
            speed = v1 - decel * braking
            tk = t[c, k] if t[c, k] <= dt else dt
            travelled[k] = v1 * tk + braking * (v1 - 0.5 * decel * braking)
            if back:
                travelled[k] = -travelled[k]
            if (drive or back) and tighten:
                left = 1.0 - (after[k] - stop) / (spin if spin >= 1e-9 else 1e-9)
                rate[k] = wc if after[k] <= stop else wc * (left if left >= 0.0 else 0.0)
            elif drive or back:
                rate[k] = wc * speed / (v1 if v1 >= 1e-9 else 1e-9)
            else:
                left = 1.0 - after[k] / (spin if spin >= 1e-9 else 1e-9)
                rate[k] = wc * (left if left >= 0.0 else 0.0)
        if not np.isnan(w_now):
            rate[0] = w_now
        # yaw by the trapezoid rule (exact where the rate is linear between samples), summed as cumsum does
        out[c, 0, 2] = 0.0
        for k in range(n - 1):
            step = (rate[k + 1] + rate[k]) * (0.5 * (t[c, k + 1] - t[c, k]))
            out[c, k + 1, 2] = step if k == 0 else out[c, k, 2] + step
        for k in range(n - 1):
            mid[c, k] = 0.5 * (out[c, k + 1, 2] + out[c, k, 2])
            ds[c, k] = travelled[k + 1] - travelled[k]
    return t, mid, ds




@njit(cache=True, nogil=True)
def wheel_sweep(v, w, v_now, w_now, dt, accel, decel, half_base, out, times):  # pragma: no cover  (compiled)
    """Poses ``out`` (C, K, 3) of the stopping sweeps of commands (``v``, ``w``: (C,)) as the
    wheels can follow them: each wheel's rim speed moves from where it is now (``v_now``,
    ``w_now``) toward the command's at most ``accel`` m/s^2 for one control period ``dt``, then
    brakes toward 0 at ``decel`` m/s^2; the K poses are evenly spaced in time over the sweep
    (their times written into ``times``, (C, K)), integrated in steps of at most 5 ms along
    each step's mean heading."""
    n_cmd, n = out.shape[0], out.shape[1]
    l0 = v_now - w_now * half_base
    r0 = v_now + w_now * half_base
    for c in range(n_cmd):
        lt = v[c] - w[c] * half_base
        rt = v[c] + w[c] * half_base
        # the rims at the end of the period
        l1 = lt if abs(lt - l0) <= accel * dt else l0 + math.copysign(accel * dt, lt - l0)
        r1 = rt if abs(rt - r0) <= accel * dt else r0 + math.copysign(accel * dt, rt - r0)
        horizon = dt + max(abs(l1), abs(r1)) / decel
        steps = int(math.ceil(horizon / 0.005))
        steps = ((steps + n - 2) // (n - 1)) * (n - 1)  # a whole number of steps between samples
        h = horizon / steps
        x = 0.0
        y = 0.0
        yaw = 0.0
        out[c, 0, 0] = 0.0
        out[c, 0, 1] = 0.0
        out[c, 0, 2] = 0.0
        per = steps // (n - 1)
        for k in range(n):
            times[c, k] = horizon * k / (n - 1)
        for i in range(steps):
            tm = (i + 0.5) * h  # the step's middle
            if tm <= dt:
                dl = lt - l0
                dr = rt - r0
                lm = lt if abs(dl) <= accel * tm else l0 + math.copysign(accel * tm, dl)
                rm = rt if abs(dr) <= accel * tm else r0 + math.copysign(accel * tm, dr)
            else:
                b = decel * (tm - dt)
                lm = 0.0 if abs(l1) <= b else l1 - math.copysign(b, l1)
                rm = 0.0 if abs(r1) <= b else r1 - math.copysign(b, r1)
            vm = 0.5 * (lm + rm)
            wm = (rm - lm) / (2.0 * half_base)
            mid = yaw + 0.5 * wm * h
            x += vm * h * math.cos(mid)
            y += vm * h * math.sin(mid)
            yaw += wm * h
            if (i + 1) % per == 0:
                k = (i + 1) // per
                out[c, k, 0] = x
                out[c, k, 1] = y
                out[c, k, 2] = yaw
    return out


@njit(cache=True, nogil=True)
def scan_points(r, cos, sin, lidar_x, max_range, join, within, fill, sin_corner):  # pragma: no cover  (compiled)
    """:meth:`~bulletnav.control.shield.Shield.points` (see there): the hits, the rebuilt
    corners, then the points filling each joined gap and each corner's two legs, in that order.
    Every value is computed by the formula, and in the order, of the array version it replaced
    (``hypot`` is the C library's in both), so the points are the same bit for bit."""
    hit, x, y = _scan_hits(r, cos, sin, lidar_x, max_range)
    span, d, pair, side = _scan_joins(hit, x, y, join)
    cb, cc, cxs, cys, nc = _scan_corners(x, y, span, d, pair, side, lidar_x, within, sin_corner)
    if within < math.inf:
        n = r.shape[0]
        for i in range(n):
            j = (i + 1) % n
            dmin = d[i] if d[i] <= d[j] else d[j]
            pair[i] = pair[i] and dmin - span[i] / 2 < within
            hit[i] = hit[i] and d[i] < within
    sx, sy, ex, ey = _scan_segments(x, y, pair, cb, cc, cxs, cys, nc)
    return _scan_fill(x, y, hit, cxs, cys, nc, sx, sy, ex, ey, fill)


@njit(cache=True, nogil=True)
def _scan_hits(r, cos, sin, lidar_x, max_range):  # pragma: no cover  (compiled)
    """Which rays hit (under 0.999 of the range), and every ray's end point in the body frame."""
    n = r.shape[0]
    x = np.empty(n)
    y = np.empty(n)
    hit = np.empty(n, dtype=np.bool_)
    for i in range(n):
        hit[i] = r[i] < max_range * 0.999
        x[i] = lidar_x + r[i] * cos[i]
        y[i] = r[i] * sin[i]
    return hit, x, y


@njit(cache=True, nogil=True)
def _scan_joins(hit, x, y, join):  # pragma: no cover  (compiled)
    """Per ray i and its next ray j: the gap's length, ray i's distance from the body centre,
    whether the gap is joined (both hit, under ``join``) and whether it lies on a surface seen
    by both (under twice ``join``)."""
    n = x.shape[0]
    span = np.empty(n)
    d = np.empty(n)
    pair = np.empty(n, dtype=np.bool_)
    side = np.empty(n, dtype=np.bool_)
    for i in range(n):
        j = (i + 1) % n
        span[i] = math.hypot(x[j] - x[i], y[j] - y[i])
        pair[i] = hit[i] and hit[j] and span[i] < join
        side[i] = hit[i] and hit[j] and span[i] < 2.0 * join
        d[i] = math.hypot(x[i], y[i])
    return span, d, pair, side


@njit(cache=True, nogil=True)
def _scan_corners(x, y, span, d, pair, side, lidar_x, within, sin_corner):  # pragma: no cover  (compiled)
    """The convex corners rebuilt in joined gaps (b, c) with one surface seen on each side (hits
    a and e): the gap's two rays, the corner's point, and their count."""
    n = x.shape[0]
    cb = np.empty(n, dtype=np.int64)
    cc = np.empty(n, dtype=np.int64)
    cxs = np.empty(n)
    cys = np.empty(n)
    nc = 0
    for b in range(n):
        if not (pair[b] and side[(b - 1) % n] and side[(b + 1) % n]):
            continue
        c = (b + 1) % n
        a = (b - 1) % n
        e = (c + 1) % n
        d1x, d1y = x[b] - x[a], y[b] - y[a]
        d2x, d2y = x[e] - x[c], y[e] - y[c]
        gx, gy = x[c] - x[b], y[c] - y[b]
        denom = d1x * d2y - d1y * d2x
        if not abs(denom) > sin_corner * math.hypot(d1x, d1y) * math.hypot(d2x, d2y):
            continue
        s1 = (gx * d2y - gy * d2x) / denom
        s2 = (gx * d1y - gy * d1x) / denom
        cx = x[b] + s1 * d1x
        cy = y[b] + s1 * d1y
        toward = (gx * (cy - y[b]) - gy * (cx - x[b])) * (gx * (0.0 - y[b]) - gy * (lidar_x - x[b])) > 0.0
        l1 = math.hypot(cx - x[b], cy - y[b])
        l2 = math.hypot(cx - x[c], cy - y[c])
        leg = l1 if l1 >= l2 else l2
        if not (s1 > 0.0 and s2 < 0.0 and toward and leg < 2.0 * span[b]):
            continue
        if within < math.inf:
            dc = math.hypot(cx, cy)
            dbc = d[b] if d[b] <= d[c] else d[c]
            if not (dc if dc <= dbc else dbc) - leg / 2 < within:
                continue
        cb[nc], cc[nc], cxs[nc], cys[nc] = b, c, cx, cy
        nc += 1
    return cb, cc, cxs, cys, nc


@njit(cache=True, nogil=True)
def _scan_segments(x, y, pair, cb, cc, cxs, cys, nc):  # pragma: no cover  (compiled)
    """The segments to fill: the joins, then every corner's first legs, then its second legs
    (start x, start y, end x, end y)."""
    n = x.shape[0]
    ns = 0
    sx = np.empty(n + 2 * nc)
    sy = np.empty(n + 2 * nc)
    ex = np.empty(n + 2 * nc)
    ey = np.empty(n + 2 * nc)
    for i in range(n):
        if pair[i]:
            j = (i + 1) % n
            sx[ns], sy[ns], ex[ns], ey[ns] = x[i], y[i], x[j], y[j]
            ns += 1
    for q in range(nc):
        sx[ns], sy[ns], ex[ns], ey[ns] = x[cb[q]], y[cb[q]], cxs[q], cys[q]
        ns += 1
    for q in range(nc):
        sx[ns], sy[ns], ex[ns], ey[ns] = cxs[q], cys[q], x[cc[q]], y[cc[q]]
        ns += 1
    return sx[:ns], sy[:ns], ex[:ns], ey[:ns]


@njit(cache=True, nogil=True)
def _scan_fill(x, y, hit, cxs, cys, nc, sx, sy, ex, ey, fill):  # pragma: no cover  (compiled)
    """The points (N, 2): the hits, the corners, then each segment's inner points every ``fill``
    m (at most 40 a segment)."""
    n, ns = x.shape[0], sx.shape[0]
    counts = np.empty(ns, dtype=np.int64)
    total = 0
    for q in range(ns):
        k = int(math.hypot(ex[q] - sx[q], ey[q] - sy[q]) / fill)
        counts[q] = k if k <= 40 else 40
        total += counts[q]
    nh = 0
    for i in range(n):
        nh += hit[i]
    pts = np.empty((nh + nc + total, 2))
    p = 0
    for i in range(n):
        if hit[i]:
            pts[p, 0], pts[p, 1] = x[i], y[i]
            p += 1
    for q in range(nc):
        pts[p, 0], pts[p, 1] = cxs[q], cys[q]
        p += 1
    for q in range(ns):
        k = counts[q]
        for m in range(1, k + 1):
            tq = m / (k + 1)
            pts[p, 0] = sx[q] + tq * (ex[q] - sx[q])
            pts[p, 1] = sy[q] + tq * (ey[q] - sy[q])
            p += 1
    return pts


@njit(cache=True, nogil=True)
def blocked_points(px, py, x0, y0, cos, sin, margin, outline):  # pragma: no cover  (compiled)
    """(C,) True where a point (``px``, ``py``: (N,)) lies in the outline (rectangles ``outline``
    (R, 4): centre x, y, half sizes) grown by ``margin[c]`` at one of command c's poses (``x0``,
    ``y0``, ``cos``, ``sin`` of the yaw: (C, K)). The same arithmetic, in the same order, as
    :func:`in_pose_frames` and the rectangle test (no fused multiply-add: numba compiles
    without fastmath), so the answers are those of the array version bit for bit; it stops at a
    command's first hit."""
    n_cmd, n_pose = cos.shape
    out = np.zeros(n_cmd, dtype=np.bool_)
    for c in range(n_cmd):
        m = margin[c]
        for k in range(n_pose):
            co, si, xk, yk = cos[c, k], sin[c, k], x0[c, k], y0[c, k]
            for n in range(px.shape[0]):
                dx = px[n] - xk
                dy = py[n] - yk
                bx = co * dx + si * dy
                by = -si * dx + co * dy
                for r in range(outline.shape[0]):
                    if abs(bx - outline[r, 0]) <= outline[r, 2] + m and abs(by - outline[r, 1]) <= outline[r, 3] + m:
                        out[c] = True
                        break
                if out[c]:
                    break
            if out[c]:
                break
    return out


@njit(cache=True, nogil=True)
def pose_gaps(px, py, x0, y0, cos, sin, outline):  # pragma: no cover  (compiled)
    """(C, K) the smallest distance (m) from a point (``px``, ``py``: (N,)) to the bare outline
    (rectangles ``outline`` (R, 4)) at each pose (``x0``, ``y0``, ``cos``, ``sin`` of the
    yaw: (C, K)); inf without points. The arithmetic of :func:`in_pose_frames` and
    ``Shield._pose_clearance``, in their order."""
    n_cmd, n_pose = cos.shape
    out = np.full((n_cmd, n_pose), np.inf)
    for c in range(n_cmd):
        for k in range(n_pose):
            co, si, xk, yk = cos[c, k], sin[c, k], x0[c, k], y0[c, k]
            best = np.inf
            for n in range(px.shape[0]):
                dx = px[n] - xk
                dy = py[n] - yk
                bx = co * dx + si * dy
                by = -si * dx + co * dy
                for r in range(outline.shape[0]):
                    ex = abs(bx - outline[r, 0]) - outline[r, 2]
                    ey = abs(by - outline[r, 1]) - outline[r, 3]
                    d = math.hypot(ex if ex > 0.0 else 0.0, ey if ey > 0.0 else 0.0)
                    if d < best:
                        best = d
            out[c, k] = best
    return out


def start_speed(v: np.ndarray, v_now: float) -> np.ndarray:
    """The speed (m/s) a sweep runs at over the control period: the larger of the current and
    the commanded forward speed when driving, of the two backward speeds when backing up, the
    current one (coasting) otherwise."""
    return np.where(v > 0, np.maximum(v_now, v), np.where(v < 0, np.maximum(-v_now, -v), max(v_now, 0.0)))


def travel(poses: np.ndarray) -> float:
    """The farthest any of the poses (C, K, 3) gets from the start (m)."""
    return float(np.sqrt((poses[:, :, 0] ** 2 + poses[:, :, 1] ** 2).max()))


def in_pose_frames(poses: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points ((N, 2), or per pose (C, K, M, 2)) in the frame of each pose (C, K, 3): x and y,
    (C, K, N) or (C, K, M)."""
    if points.ndim == 2:
        points = points[None, None]
    px = points[..., 0] - poses[:, :, 0, None]
    py = points[..., 1] - poses[:, :, 1, None]
    c, s = np.cos(poses[:, :, 2])[..., None], np.sin(poses[:, :, 2])[..., None]
    return c * px + s * py, -s * px + c * py


__all__ = ["blocked_points", "in_pose_frames", "pose_gaps", "scan_points", "start_speed", "sweep_profile", "travel"]

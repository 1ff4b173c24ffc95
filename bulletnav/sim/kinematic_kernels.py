"""Compiled (numba, ``cache=True``) kernels of the kinematic profile's step: the drive, the
contact test and the lidar's closed-form casts, in the same arithmetic as the Python they
replace (:class:`bulletnav.sim.kinematic.KinematicRobot`, :func:`bulletnav.sim.kinematic._boxes_meet`,
:class:`bulletnav.sensors.raycast.ExactCaster`); ``tests/test_kinematic_kernels.py`` checks them
against that code on random inputs.

Shapes are plain arrays:

- boxes ``(M, 8)``: centre x, y, cos and sin of the yaw, half sizes x, y, centre z, half height;
- cylinders ``(C, 5)``: centre x, y, radius, centre z, half height;
- the robot's collision rectangles ``(K, 4)`` in its body frame: centre x, y, half x, half y.

The lidar kernels are for level rays (the lidar's, always horizontal here). :func:`cast_level`
tests each shape only against the rays inside the angle its bounding circle subtends from the
lidar, so a scan costs what the shapes cover, not rays times shapes; :func:`cast_grid`, for many
shapes (a BARN world's cylinders), walks each ray through a grid of them (:func:`shape_grid`),
leaping through empty cells, and tests only the shapes of the cells it crosses before its hit.
Both give the same distances, to the bit.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

TWO_PI = 2.0 * math.pi


@njit(cache=True, nogil=True)
def wrap(yaw: float) -> float:
    """``math.remainder(yaw, 2 pi)``, bit for bit where ``|yaw| < 3 pi`` (Sterbenz: the one
    subtraction is exact there), which a substep's yaw always is."""
    if -3.0 * math.pi < yaw < 3.0 * math.pi:
        if yaw > math.pi:
            return yaw - TWO_PI
        if yaw < -math.pi:
            return yaw + TWO_PI
        return yaw
    n = np.round(yaw / TWO_PI)  # far out (never on a substep): round half to even, as remainder does
    return yaw - n * TWO_PI


@njit(cache=True, nogil=True)
def next_rims(left: float, right: float, tl: float, tr: float, a: float, b: float, dt: float, limit: float,
              iterations: int) -> tuple[float, float]:
    """:meth:`KinematicRobot.next_rims`: the rim speeds after one substep."""
    if left == tl and right == tr:
        return left, right
    el = (tl - left) / dt
    er = (tr - right) / dt
    det = a * a - b * b
    fl = (a * el - b * er) / det
    fr = (a * er - b * el) / det
    if abs(fl) > limit or abs(fr) > limit:
        fl = max(-limit, min(limit, fl))
        fr = max(-limit, min(limit, fr))
        for _ in range(iterations):
            fl = max(-limit, min(limit, (el - b * fr) / a))
            fr = max(-limit, min(limit, (er - b * fl) / a))
    nl = left + (a * fl + b * fr) * dt
    nr = right + (a * fr + b * fl) * dt
    if abs(nl - tl) < 1e-12:
        nl = tl
    if abs(nr - tr) < 1e-12:
        nr = tr
    return nl, nr


@njit(cache=True, nogil=True)
def advance(x: float, y: float, yaw: float, left: float, right: float, wheelbase: float,
            dt: float) -> tuple[float, float, float]:
    """:meth:`KinematicRobot.advance`: the pose after ``dt`` at rim speeds (left, right), an exact arc."""
    v = (left + right) / 2
    w = (right - left) / wheelbase
    dyaw = w * dt
    if abs(dyaw) < 1e-9:
        mid = yaw + dyaw / 2
        ds = v * dt
        return x + ds * math.cos(mid), y + ds * math.sin(mid), yaw + dyaw
    r = v / w
    return x + r * (math.sin(yaw + dyaw) - math.sin(yaw)), y - r * (math.cos(yaw + dyaw) - math.cos(yaw)), yaw + dyaw


@njit(cache=True, nogil=True)
def rectangles(x: float, y: float, yaw: float, body: np.ndarray, out: np.ndarray) -> None:
    """:meth:`KinematicRobot.rectangles` into ``out`` (K x 6: centre x, y, cos, sin, half x, half y)."""
    c = math.cos(yaw)
    s = math.sin(yaw)
    for k in range(body.shape[0]):
        out[k, 0] = x + c * body[k, 0] - s * body[k, 1]
        out[k, 1] = y + s * body[k, 0] + c * body[k, 1]
        out[k, 2] = c
        out[k, 3] = s
        out[k, 4] = body[k, 2]
        out[k, 5] = body[k, 3]


@njit(cache=True, nogil=True)
def _box_meets(rects: np.ndarray, bx: float, by: float, bc: float, bs: float, bhx: float, bhy: float,
               margin: float) -> bool:
    # separating axes, the operations of kinematic._boxes_meet in its order
    for k in range(rects.shape[0]):
        rx, ry, rc, rs, rhx, rhy = rects[k, 0], rects[k, 1], rects[k, 2], rects[k, 3], rects[k, 4], rects[k, 5]
        dx = bx - rx
        dy = by - ry
        separated = False
        for axis in range(4):
            if axis == 0:
                ux, uy = rc, rs
            elif axis == 1:
                ux, uy = -rs, rc
            elif axis == 2:
                ux, uy = bc, bs
            else:
                ux, uy = -bs, bc
            reach = (rhx * abs(ux * rc + uy * rs) + rhy * abs(-ux * rs + uy * rc)
                     + bhx * abs(ux * bc + uy * bs) + bhy * abs(-ux * bs + uy * bc))
            if abs(dx * ux + dy * uy) > reach + margin:
                separated = True
                break
        if not separated:
            return True
    return False


@njit(cache=True, nogil=True)
def _circle_meets(rects: np.ndarray, x: float, y: float, radius: float, margin: float) -> bool:
    for k in range(rects.shape[0]):
        rx, ry, rc, rs, rhx, rhy = rects[k, 0], rects[k, 1], rects[k, 2], rects[k, 3], rects[k, 4], rects[k, 5]
        dx = x - rx
        dy = y - ry
        lx = rc * dx + rs * dy
        ly = -rs * dx + rc * dy
        ex = max(abs(lx) - rhx, 0.0)
        ey = max(abs(ly) - rhy, 0.0)
        if ex * ex + ey * ey <= (radius + margin) ** 2:
            return True
    return False


@njit(cache=True, nogil=True)
def overlaps(rects: np.ndarray, cx: float, cy: float, reach: float, margin: float, boxes: np.ndarray,
             box_reach: np.ndarray, cyls: np.ndarray, box_hit: np.ndarray, cyl_hit: np.ndarray, first: bool) -> bool:
    """Whether ``rects`` meet any of the shapes once both are grown by ``margin``; ``reach``:
    the rectangles' farthest point from (cx, cy). With ``first``, True at the first shape met
    and nothing marked; else every shape met is marked in ``box_hit`` / ``cyl_hit``."""
    anything = False
    for i in range(boxes.shape[0]):
        if math.hypot(boxes[i, 0] - cx, boxes[i, 1] - cy) <= box_reach[i] + reach + margin:
            if _box_meets(rects, boxes[i, 0], boxes[i, 1], boxes[i, 2], boxes[i, 3], boxes[i, 4], boxes[i, 5], margin):
                if first:
                    return True
                box_hit[i] = True
                anything = True
    for i in range(cyls.shape[0]):
        if math.hypot(cyls[i, 0] - cx, cyls[i, 1] - cy) <= cyls[i, 2] + reach + margin:
            if _circle_meets(rects, cyls[i, 0], cyls[i, 1], cyls[i, 2], margin):
                if first:
                    return True
                cyl_hit[i] = True
                anything = True
    return anything


@njit(cache=True, nogil=True)
def drive(n: int, state: np.ndarray, target_l: float, target_r: float, a: float, b: float, dt: float, limit: float,
          iterations: int, wheelbase: float, wheel_radius: float, body: np.ndarray, reach: float, sweep: float,
          boxes: np.ndarray, box_reach: np.ndarray, cyls: np.ndarray, box_hit: np.ndarray, cyl_hit: np.ndarray,
          moving_always: bool, mboxes: np.ndarray, mbox_reach: np.ndarray, mcyls: np.ndarray, mbox_hit: np.ndarray,
          mcyl_hit: np.ndarray) -> bool:
    """``n`` substeps of :meth:`KinematicSimulation.step`; True when a shape was touched.

    ``state`` (7,): rims left, right (m/s), pose x, y, yaw, wheel angles left, right, updated in
    place. The static shapes, and the moving ones, are checked at every substep when any of
    them lies within ``sweep`` (m: how far the outline can move in the ``n`` substeps) of the
    outline now; the moving ones always with ``moving_always`` (they move between calls). A
    substep whose pose would overlap a checked shape is not taken: the rims stop, the shapes
    touched are marked in the ``*_hit`` arrays."""
    rects = np.empty((body.shape[0], 6))
    rectangles(state[2], state[3], state[4], body, rects)
    check_static = overlaps(rects, state[2], state[3], reach, sweep, boxes, box_reach, cyls, box_hit, cyl_hit, True)
    check_moving = moving_always or overlaps(rects, state[2], state[3], reach, sweep, mboxes, mbox_reach, mcyls,
                                             mbox_hit, mcyl_hit, True)
    touched = False
    for _ in range(n):
        left, right = next_rims(state[0], state[1], target_l, target_r, a, b, dt, limit, iterations)
        x, y, yaw = advance(state[2], state[3], state[4], left, right, wheelbase, dt)
        if check_static or check_moving:
            rectangles(x, y, yaw, body, rects)
            hit = False
            if check_static:
                hit = overlaps(rects, x, y, reach, 0.0, boxes, box_reach, cyls, box_hit, cyl_hit, False)
            if check_moving:
                hit = overlaps(rects, x, y, reach, 0.0, mboxes, mbox_reach, mcyls, mbox_hit, mcyl_hit, False) or hit
            if hit:
                touched = True
                state[0] = 0.0
                state[1] = 0.0
                continue
        state[5] = state[5] + left * dt / wheel_radius
        state[6] = state[6] + right * dt / wheel_radius
        state[0] = left
        state[1] = right
        state[2] = x
        state[3] = y
        state[4] = wrap(yaw)
    return touched


# ---------------------------------------------------------------------------------------- the lidar
@njit(cache=True, nogil=True)
def _cylinder_t(ox: float, oy: float, dx: float, dy: float, cx: float, cy: float, r: float) -> float:
    # ExactCaster._cylinders for one level ray (inside the cylinder's height)
    relx = cx - ox
    rely = cy - oy
    a = dx * dx + dy * dy
    b = -(dx * relx + dy * rely)
    c = relx * relx + rely * rely - r * r
    disc = b * b - a * c
    if disc < 0.0:
        return np.inf
    root = math.sqrt(disc)
    t_in = (-b - root) / a
    t_out = (-b + root) / a
    if t_out < 0.0:
        return np.inf
    return max(t_in, 0.0)


@njit(cache=True, nogil=True)
def _box_t(ox: float, oy: float, dx: float, dy: float, bx: float, by: float, bc: float, bs: float,
           hx: float, hy: float) -> float:
    # ExactCaster._boxes for one level ray (inside the box's height): slab test in the box's frame
    rx = ox - bx
    ry = oy - by
    lox = bc * rx + bs * ry
    loy = -bs * rx + bc * ry
    ldx = dx * bc + dy * bs
    ldy = dy * bc - dx * bs
    if ldx == 0.0:
        ldx = 1e-300
    if ldy == 0.0:
        ldy = 1e-300
    t1 = (-hx - lox) / ldx
    t2 = (hx - lox) / ldx
    t3 = (-hy - loy) / ldy
    t4 = (hy - loy) / ldy
    enter = max(min(t1, t2), min(t3, t4))
    leave = min(max(t1, t2), max(t3, t4))
    if enter <= leave and leave >= 0.0:
        return max(enter, 0.0)
    return np.inf


@njit(cache=True, nogil=True)
def cast_level(ox: float, oy: float, oz: float, yaw: float, cos_a: np.ndarray, sin_a: np.ndarray, a0: float,
               da: float, boxes: np.ndarray, cyls: np.ndarray, length: float, out: np.ndarray) -> None:
    """Lower ``out[i]`` to the distance along level ray ``i`` to its nearest hit among the
    shapes (``inf`` stays where nothing lies within ``length``).

    Ray ``i`` leaves (ox, oy, oz) at angle ``yaw + a_i`` (``cos_a``, ``sin_a`` of ``a_i``); the
    ``a_i`` run from ``a0`` in steps of about ``da``. A shape is tested
    against the rays within the angle its bounding circle subtends (every ray where the origin
    lies inside that circle), nearest first, and skipped where every ray of that angle already
    hits nearer than the circle comes; a shape whose height range misses ``oz`` is never hit."""
    n = cos_a.shape[0]
    cy_, sy_ = math.cos(yaw), math.sin(yaw)
    dxs = np.empty(n)
    dys = np.empty(n)
    for i in range(n):
        dxs[i] = cos_a[i] * cy_ - sin_a[i] * sy_
        dys[i] = sin_a[i] * cy_ + cos_a[i] * sy_
    # nearest first, so that a shape wholly behind what its rays already hit is skipped (_scan)
    if boxes.shape[0]:
        near = np.empty(boxes.shape[0])
        for j in range(boxes.shape[0]):
            near[j] = math.hypot(boxes[j, 0] - ox, boxes[j, 1] - oy) - math.hypot(boxes[j, 4], boxes[j, 5])
        for j in np.argsort(near):
            if abs(oz - boxes[j, 6]) <= boxes[j, 7]:
                _scan(True, boxes[j], math.hypot(boxes[j, 4], boxes[j, 5]), ox, oy, yaw, a0, da, dxs, dys, length, out)
    if cyls.shape[0]:
        near = np.empty(cyls.shape[0])
        for j in range(cyls.shape[0]):
            near[j] = math.hypot(cyls[j, 0] - ox, cyls[j, 1] - oy) - cyls[j, 2]
        for j in np.argsort(near):
            if abs(oz - cyls[j, 3]) <= cyls[j, 4]:
                _scan(False, cyls[j], cyls[j, 2], ox, oy, yaw, a0, da, dxs, dys, length, out)


@njit(cache=True, nogil=True)
def _scan(is_box: bool, shape: np.ndarray, radius: float, ox: float, oy: float, yaw: float, a0: float, da: float,
          dxs: np.ndarray, dys: np.ndarray, length: float, out: np.ndarray) -> None:
    # one shape against the rays within the angle its bounding circle (``radius`` about its
    # centre) subtends: the ray angles a0 + i da taken modulo 2 pi, so the window is looked for
    # a turn either side too, and widened by a ray each side (the angles are only nearly uniform)
    n = dxs.shape[0]
    cx, cy = shape[0], shape[1]
    d = math.hypot(cx - ox, cy - oy)
    if d - radius > length:
        return
    if d <= radius * 1.000001 + 1e-9:  # the origin within the bounding circle: every ray
        _rays(is_box, shape, ox, oy, dxs, dys, 0, n - 1, out)
        return
    half = math.asin(radius / d) + 1e-6
    phi = math.atan2(cy - oy, cx - ox) - yaw - a0
    phi = phi - TWO_PI * math.floor(phi / TWO_PI)  # [0, 2 pi)
    lo1 = lo2 = lo3 = 1
    hi1 = hi2 = hi3 = 0
    k = 0
    last = -1
    behind = True  # every ray of the window already hits nearer than this shape can be (d - radius)
    for shift in (-TWO_PI, 0.0, TWO_PI):
        lo = max(int(math.ceil((phi - half + shift) / da)) - 1, 0, last + 1)
        hi = min(int(math.floor((phi + half + shift) / da)) + 1, n - 1)
        if lo <= hi:
            if k == 0:
                lo1, hi1 = lo, hi
            elif k == 1:
                lo2, hi2 = lo, hi
            else:
                lo3, hi3 = lo, hi
            k += 1
            last = hi
            for i in range(lo, hi + 1):
                if out[i] > d - radius:
                    behind = False
    if behind:
        return
    _rays(is_box, shape, ox, oy, dxs, dys, lo1, hi1, out)
    _rays(is_box, shape, ox, oy, dxs, dys, lo2, hi2, out)
    _rays(is_box, shape, ox, oy, dxs, dys, lo3, hi3, out)


@njit(cache=True, nogil=True)
def _rays(is_box: bool, shape: np.ndarray, ox: float, oy: float, dxs: np.ndarray, dys: np.ndarray, lo: int, hi: int,
          out: np.ndarray) -> None:
    for i in range(lo, hi + 1):
        if is_box:
            t = _box_t(ox, oy, dxs[i], dys[i], shape[0], shape[1], shape[2], shape[3], shape[4], shape[5])
        else:
            t = _cylinder_t(ox, oy, dxs[i], dys[i], shape[0], shape[1], shape[2])
        if t < out[i]:
            out[i] = t


@njit(cache=True, nogil=True)
def _slab(o: float, d: float, lo: float, hi: float, t0: float, t1: float) -> tuple[float, float]:
    # the ray's parameter range [t0, t1] narrowed to where o + t d lies in [lo, hi] (empty: t0 > t1)
    if d != 0.0:
        ta, tb = (lo - o) / d, (hi - o) / d
        return max(t0, min(ta, tb)), min(t1, max(ta, tb))
    if lo <= o <= hi:
        return t0, t1
    return 1.0, 0.0


@njit(cache=True, nogil=True)
def _walk_axis(o: float, d: float, g: float, cell: float, index: int) -> tuple[int, float, float]:
    # Amanatides and Woo along one axis: the step, the t of the next cell edge, the t between edges
    if d > 0.0:
        return 1, (g + (index + 1) * cell - o) / d, cell / d
    if d < 0.0:
        return -1, (g + index * cell - o) / d, -cell / d
    return 0, np.inf, np.inf


@njit(cache=True, nogil=True)
def _cell_nearest(c: int, ray: int, ox: float, oy: float, oz: float, dx: float, dy: float, boxes: np.ndarray,
                  cyls: np.ndarray, starts: np.ndarray, items: np.ndarray, tested: np.ndarray, best: float) -> float:
    # ``best`` lowered by the shapes of cell ``c`` not yet tested against this ray
    nb = boxes.shape[0]
    for k in range(starts[c], starts[c + 1]):
        j = items[k]
        if tested[j] == ray:
            continue
        tested[j] = ray
        if j < nb:
            if abs(oz - boxes[j, 6]) <= boxes[j, 7]:
                best = min(best, _box_t(ox, oy, dx, dy, boxes[j, 0], boxes[j, 1], boxes[j, 2], boxes[j, 3],
                                        boxes[j, 4], boxes[j, 5]))
        elif abs(oz - cyls[j - nb, 3]) <= cyls[j - nb, 4]:
            best = min(best, _cylinder_t(ox, oy, dx, dy, cyls[j - nb, 0], cyls[j - nb, 1], cyls[j - nb, 2]))
    return best


@njit(cache=True, nogil=True)
def cast_grid(ox: float, oy: float, oz: float, yaw: float, cos_a: np.ndarray, sin_a: np.ndarray,
              boxes: np.ndarray, cyls: np.ndarray, gx: float, gy: float, cell: float, nx: int, ny: int,
              starts: np.ndarray, items: np.ndarray, empty: np.ndarray, length: float, out: np.ndarray) -> None:
    """:func:`cast_level` through a uniform grid: ray ``i`` walks the cells it crosses, nearest
    first (Amanatides and Woo's traversal), tests the shapes listed in each (``starts``,
    ``items``: cell ``(ix, iy)`` = ``ix * ny + iy`` lists ``items[starts[c]:starts[c + 1]]``,
    box ``k`` as ``k``, cylinder ``k`` as ``len(boxes) + k``, each in every cell its bounding
    box touches) and stops once its nearest hit lies before the cell's far side: a shape not yet
    tested meets the ray only in a later cell, so the result is the least over every shape,
    the same numbers as testing them all. Through empty space it leaps: ``empty[c]`` is the
    chessboard distance (cells) from cell ``c`` to the nearest listing a shape, and the ray goes
    on ``(empty[c] - 1) * cell`` m at once, a stretch that lies in empty cells only. The grid's
    lower corner is (``gx``, ``gy``), its cells ``cell`` m square. Shapes whose height range
    misses ``oz`` are never hit."""
    tested = np.full(boxes.shape[0] + cyls.shape[0], -1, np.int64)
    cy_, sy_ = math.cos(yaw), math.sin(yaw)
    for i in range(cos_a.shape[0]):
        dx = cos_a[i] * cy_ - sin_a[i] * sy_
        dy = sin_a[i] * cy_ + cos_a[i] * sy_
        best = out[i]
        t0, t1 = _slab(ox, dx, gx, gx + nx * cell, 0.0, min(length, best))  # the stretch inside the grid
        t0, t1 = _slab(oy, dy, gy, gy + ny * cell, t0, t1)
        enter = t0  # where the ray enters the cell it is in
        while enter <= t1:
            ix = min(max(int(math.floor((ox + enter * dx - gx) / cell)), 0), nx - 1)
            iy = min(max(int(math.floor((oy + enter * dy - gy) / cell)), 0), ny - 1)
            leap = empty[ix * ny + iy] - 1
            if leap >= 1:  # every cell within ``leap`` of this one is empty
                enter += leap * cell * (1.0 - 1e-12)
                continue
            step_x, next_x, delta_x = _walk_axis(ox, dx, gx, cell, ix)
            step_y, next_y, delta_y = _walk_axis(oy, dy, gy, cell, iy)
            while True:  # cell by cell while shapes are near
                c = ix * ny + iy
                best = _cell_nearest(c, i, ox, oy, oz, dx, dy, boxes, cyls, starts, items, tested, best)
                far = min(next_x, next_y)  # where the ray leaves this cell
                if best < far - 1e-9 or far > min(t1, best) + 1e-9:
                    enter = np.inf
                    break
                if next_x < next_y:
                    ix += step_x
                    next_x += delta_x
                else:
                    iy += step_y
                    next_y += delta_y
                if not (0 <= ix < nx and 0 <= iy < ny):
                    enter = np.inf
                    break
                leap = empty[ix * ny + iy] - 1
                if leap >= 2:  # open space ahead: leap from where the ray enters this cell (never back)
                    enter = far + leap * cell * (1.0 - 1e-12)
                    break
        out[i] = best


@njit(cache=True, nogil=True)
def shape_grid(boxes: np.ndarray, cyls: np.ndarray, min_cell: float, max_cell: float, max_cells: int):  # noqa: ANN201
    """The grid :func:`cast_grid` walks, for boxes and cylinders as :func:`cast_level` takes them:
    ``(gx, gy, cell, nx, ny, starts, items, empty)``. Cells are four times the median shape's
    smaller half extent (within ``min_cell``-``max_cell`` m, and larger where that would make more
    than ``max_cells``); each lists the shapes whose bounding box, grown by 1 um (a hit on a
    cell's edge is listed on both sides), touches it; ``empty`` is each cell's chessboard distance
    (cells) to the nearest cell listing a shape (0 there), by a two-pass chamfer."""
    nb, nc = boxes.shape[0], cyls.shape[0]
    n = nb + nc
    lo_x, hi_x, lo_y, hi_y, small = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    for j in range(n):
        if j < nb:
            c, s = abs(boxes[j, 2]), abs(boxes[j, 3])
            ex, ey = c * boxes[j, 4] + s * boxes[j, 5], s * boxes[j, 4] + c * boxes[j, 5]
            x, y = boxes[j, 0], boxes[j, 1]
        else:
            ex = ey = cyls[j - nb, 2]
            x, y = cyls[j - nb, 0], cyls[j - nb, 1]
        lo_x[j], hi_x[j], lo_y[j], hi_y[j], small[j] = x - ex - 1e-6, x + ex + 1e-6, y - ey - 1e-6, y + ey + 1e-6, min(ex, ey)
    gx, gy = lo_x.min(), lo_y.min()
    width, height = hi_x.max() - gx, hi_y.max() - gy
    cell = max(min(max(4.0 * np.median(small), min_cell), max_cell), math.sqrt(width * height / max_cells))
    nx, ny = max(1, int(math.ceil(width / cell))), max(1, int(math.ceil(height / cell)))
    ix0, ix1, iy0, iy1 = np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n, np.int64)
    starts = np.zeros(nx * ny + 1, np.int64)
    for j in range(n):
        ix0[j] = min(max(int(math.floor((lo_x[j] - gx) / cell)), 0), nx - 1)
        ix1[j] = min(max(int(math.floor((hi_x[j] - gx) / cell)), 0), nx - 1)
        iy0[j] = min(max(int(math.floor((lo_y[j] - gy) / cell)), 0), ny - 1)
        iy1[j] = min(max(int(math.floor((hi_y[j] - gy) / cell)), 0), ny - 1)
        for ix in range(ix0[j], ix1[j] + 1):
            for iy in range(iy0[j], iy1[j] + 1):
                starts[ix * ny + iy + 1] += 1
    for c in range(nx * ny):
        starts[c + 1] += starts[c]
    items = np.empty(starts[-1], np.int64)
    fill = starts[:-1].copy()
    for j in range(n):  # in shape order within each cell
        for ix in range(ix0[j], ix1[j] + 1):
            for iy in range(iy0[j], iy1[j] + 1):
                items[fill[ix * ny + iy]] = j
                fill[ix * ny + iy] += 1
    return gx, gy, cell, nx, ny, starts, items, _chessboard(starts, nx, ny)


@njit(cache=True, nogil=True)
def _chessboard(starts: np.ndarray, nx: int, ny: int) -> np.ndarray:
    # each cell's chessboard distance (cells) to the nearest cell listing a shape: a two-pass chamfer
    far = nx + ny
    empty = np.empty(nx * ny, np.int64)
    for c in range(nx * ny):
        empty[c] = 0 if starts[c + 1] > starts[c] else far
    for ix in range(nx):  # forward pass: the neighbours already visited (left column, the cell below)
        for iy in range(ny):
            d = empty[ix * ny + iy]
            for ax, ay in ((-1, -1), (-1, 0), (-1, 1), (0, -1)):
                jx, jy = ix + ax, iy + ay
                if 0 <= jx < nx and 0 <= jy < ny:
                    d = min(d, empty[jx * ny + jy] + 1)
            empty[ix * ny + iy] = d
    for ix in range(nx - 1, -1, -1):  # backward pass
        for iy in range(ny - 1, -1, -1):
            d = empty[ix * ny + iy]
            for ax, ay in ((1, 1), (1, 0), (1, -1), (0, 1)):
                jx, jy = ix + ax, iy + ay
                if 0 <= jx < nx and 0 <= jy < ny:
                    d = min(d, empty[jx * ny + jy] + 1)
            empty[ix * ny + iy] = d
    return empty

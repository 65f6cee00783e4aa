"""Pure geometry of the table world (SPEC §1, §3): motion, sensors, squares, kill zone, docking.

Frames: arena units (1 unit = 1 cm), origin at the south-west corner, x east, y north; headings
in degrees in [0, 360), 0 = north (+y), 90 = east, clockwise positive. Bearings relative to
the heading are in (−180, 180], negative = left.

Two layers:
- scalar kernels (``move``, ``object_bits``, ``disc_bits``, ``block_bits``, ``too_close``,
  ``block_stops``, ``light_bits``, ``square_at``, ``killed``, ``docked``, ...) over a *packed*
  settings vector ``p`` (``pack_world``). They use only ``math`` and indexing, so the numba
  kernel compiles these very functions: the interpreter and the kernel share every float
  formula, operation for operation. Other robots of a colony (SPEC §7) are discs:
  ``disc_bits`` (object sensors) and ``too_close`` (cancelled moves). An envelope's station
  (SPEC §9) is a box: ``block_bits`` (object sensors), ``block_stops`` (stopped moves) and
  ``block_slide_end`` (a stopped move slid along it).
  ``wall_bits`` and ``disc_bits_within`` take the activation distance as an argument (an
  envelope draws it per run).
- public wrappers over ``WorldSettings`` (``apply_gait``, ``light_sensors``, ...).

Square index: square (i, j) with i the column (x) and j the row (y) has index i + grid_n·j.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba.extending import register_jitable

from evolve.codec import LIGHT_LEFT, LIGHT_RIGHT, OBJECT_LEFT, OBJECT_RIGHT
from evolve.settings import WorldSettings

DEG2RAD = math.pi / 180.0
RAD2DEG = 180.0 / math.pi
DEFAULT_WORLD = WorldSettings()
"""The SPEC's world, the default of every function here."""
MAX_SQUARES = 128
"""The kernel tracks reached squares in two uint64 masks: grid_n² must not exceed this."""

# Layout of the packed settings vector (float64), one named index per WorldSettings value.
P_ARENA = 0
P_GRID_N = 1
P_SQUARE = 2
P_CONTACT = 3
P_KILL = 4
P_STATION_Y = 5
P_DOCK_X = 6
P_DOCK_YHW = 7
P_DOCK_H = 8
P_DOCK_HTOL = 9
P_LIGHT_AXIS = 10
P_LIGHT_HALF = 11
P_LL_A = 12
P_LL_B = 13
P_LR_A = 14
P_LR_B = 15
P_OL_A = 16
P_OL_B = 17
P_OR_A = 18
P_OR_B = 19
P_OBJ_RANGE = 20
P_COST = 21
"""The paper's constant ``gait_cost_v`` and ``still_gait`` (P_STILL), kept for reference: what a
cycle costs is read from the ``P_GAIT_COST`` block only."""
P_STILL = 22
P_LOW = 23
P_EMPTY = 24
P_CHARGED = 25
P_BACKUP_GAIT = 26
P_BACKUP_N = 27
P_MAX_BRANCH = 28
P_GAIT_COST = 29
"""Power used by one cycle of gait g, volts, is p[P_GAIT_COST + g] (16 entries, the power model
``WorldSettings.gait_costs_v``: the kernel and the interpreter read only these)."""
P_N_LIGHTS = P_GAIT_COST + 16
P_LIGHTS = P_N_LIGHTS + 1
"""Light k sits at (p[P_LIGHTS + 2k], p[P_LIGHTS + 2k + 1])."""


def pack_world(world: WorldSettings = DEFAULT_WORLD) -> np.ndarray:
    """Pack ``world`` into the float64 vector the scalar kernels read (read-only)."""
    return _pack_cached(world)


@functools.lru_cache(maxsize=32)
def _pack_cached(world: WorldSettings) -> np.ndarray:
    n = int(world.grid_n)
    if n < 1 or n * n > MAX_SQUARES:
        raise ValueError(f"grid_n = {n}: need 1 ≤ grid_n² ≤ {MAX_SQUARES}")
    if not 0 <= world.still_gait < 16 or not 0 <= world.backup_gait < 16:
        raise ValueError("still_gait and backup_gait must be gaits 0-15")
    for span in (
        world.light_left_span_deg,
        world.light_right_span_deg,
        world.object_left_span_deg,
        world.object_right_span_deg,
    ):
        if not -180.0 < span[0] <= span[1] <= 180.0:
            raise ValueError(f"sensor span {span} must satisfy -180 < a <= b <= 180")
    vals = [0.0] * P_LIGHTS
    vals[P_ARENA] = world.arena_size
    vals[P_GRID_N] = n
    vals[P_SQUARE] = world.square_size
    vals[P_CONTACT] = world.contact_half_width
    vals[P_KILL] = world.kill_margin
    vals[P_STATION_Y] = world.station_y
    vals[P_DOCK_X] = world.dock_x_min
    vals[P_DOCK_YHW] = world.dock_y_half_width
    vals[P_DOCK_H] = world.dock_heading_deg
    vals[P_DOCK_HTOL] = world.dock_heading_tol_deg
    vals[P_LIGHT_AXIS] = world.light_axis_deg
    vals[P_LIGHT_HALF] = world.light_half_angle_deg
    vals[P_LL_A], vals[P_LL_B] = world.light_left_span_deg
    vals[P_LR_A], vals[P_LR_B] = world.light_right_span_deg
    vals[P_OL_A], vals[P_OL_B] = world.object_left_span_deg
    vals[P_OR_A], vals[P_OR_B] = world.object_right_span_deg
    vals[P_OBJ_RANGE] = world.object_range
    vals[P_COST] = world.gait_cost_v
    vals[P_STILL] = world.still_gait
    vals[P_LOW] = world.low_power_v
    vals[P_EMPTY] = world.empty_power_v
    vals[P_CHARGED] = world.charged_power_v
    vals[P_BACKUP_GAIT] = world.backup_gait
    vals[P_BACKUP_N] = world.backup_cycles
    vals[P_MAX_BRANCH] = world.max_consecutive_branches
    vals[P_GAIT_COST : P_GAIT_COST + 16] = world.gait_costs_v()
    vals[P_N_LIGHTS] = len(world.lights)
    for sx, sy in world.lights:
        vals += [float(sx), float(sy)]
    arr = np.array(vals, dtype=np.float64)
    arr.setflags(write=False)
    return arr


@functools.lru_cache(maxsize=32)
def packed_tuple(world: WorldSettings) -> tuple[float, ...]:
    """The packed vector as a tuple of Python floats (fast indexing in plain Python)."""
    return tuple(float(v) for v in pack_world(world))


# ---------------------------------------------------------------------------------------
# Scalar kernels: plain ``math``; ``register_jitable`` leaves them plain Python when called
# from Python and lets the numba kernel compile the very same code.
# ---------------------------------------------------------------------------------------


@register_jitable
def wrap360(a):
    """Angle in degrees wrapped into [0, 360)."""
    if 0.0 < a < 360.0:  # already wrapped: what the modulo returns, without its cost
        return a
    r = a % 360.0  # Python float modulo (numba implements the same), in [0, 360]
    if r >= 360.0:
        r -= 360.0
    return r


@register_jitable
def wrap180(a):
    """Angle in degrees wrapped into (−180, 180]."""
    return 180.0 - wrap360(180.0 - a)


@register_jitable
def move(x, y, h, f, t, dh):
    """One gait cycle (SPEC §1): (F, T) in the frame at the cycle's start, then turn by dH.

    ``x += F·sin h + T·cos h;  y += F·cos h − T·sin h;  h = (h + dH) mod 360``.
    """
    r = h * DEG2RAD
    s = math.sin(r)
    c = math.cos(r)
    return x + (f * s + t * c), y + (f * c - t * s), wrap360(h + dh)


@register_jitable
def _span_offset(rel, a, b):
    """Angle (deg, in [0, 180]) from relative bearing ``rel`` to the closest direction of
    span [a, b]; 0 when ``rel`` lies in the span."""
    u = wrap360(rel - a)
    w = b - a
    if u <= w:
        return 0.0
    return min(u - w, 360.0 - u)


@register_jitable
def _span_reaches(rel, a, b, dist, reach):
    """Whether a wall at perpendicular ``dist`` whose normal lies at relative bearing ``rel``
    is within ``reach`` along the direction of span [a, b] closest to that normal."""
    delta = _span_offset(rel, a, b)
    if delta >= 90.0:
        return False
    return dist <= reach * math.cos(delta * DEG2RAD)


@register_jitable
def _disc_reaches(rel, a, b, dist, radius, reach):
    """Whether some point of a disc (``radius``; centre at ``dist`` > ``radius``, relative
    bearing ``rel``) lies within ``reach`` along a direction of span [a, b].

    The closest such point lies on the span direction closest to the centre, δ off it: that
    ray enters the disc at d·cos δ − √(r² − d²·sin² δ), and misses it if d·sin δ > r."""
    delta = _span_offset(rel, a, b)
    if delta == 0.0:
        return dist - radius <= reach
    if delta >= 90.0:
        return False
    r = delta * DEG2RAD
    off = dist * math.sin(r)
    if off > radius:
        return False
    return dist * math.cos(r) - math.sqrt(radius * radius - off * off) <= reach


@register_jitable
def object_bits(x, y, h, p):
    """Active object-sensor bits (OBJECT_LEFT | OBJECT_RIGHT) at pose (x, y, h), walls only,
    within the world's activation distance P_OBJ_RANGE."""
    return wall_bits(x, y, h, p[P_OBJ_RANGE], p)


@register_jitable
def wall_bits(x, y, h, reach, p):
    """Object-sensor bits that the walls activate at pose (x, y, h) within ``reach`` units (an
    envelope's per-run activation distance, SPEC §9; else P_OBJ_RANGE)."""
    size = p[P_ARENA]
    bits = 0
    for wall in range(4):
        if wall == 0:  # north wall y = size, outward normal bearing 0
            dist = size - y
            normal = 0.0
        elif wall == 1:  # east wall x = size
            dist = size - x
            normal = 90.0
        elif wall == 2:  # south wall y = 0
            dist = y
            normal = 180.0
        else:  # west wall x = 0
            dist = x
            normal = 270.0
        if dist > reach:
            continue
        rel = wrap180(normal - h)
        if _span_reaches(rel, p[P_OL_A], p[P_OL_B], dist, reach):
            bits |= OBJECT_LEFT
        if _span_reaches(rel, p[P_OR_A], p[P_OR_B], dist, reach):
            bits |= OBJECT_RIGHT
    return bits


@register_jitable
def disc_bits(x, y, h, ox, oy, radius, p):
    """Object-sensor bits (OBJECT_LEFT | OBJECT_RIGHT) that another robot, a disc of
    ``radius`` centred at (ox, oy), activates at pose (x, y, h) (SPEC §7): a span is active if
    some point of the disc lies within P_OBJ_RANGE along a direction in the span."""
    return disc_bits_within(x, y, h, ox, oy, radius, p[P_OBJ_RANGE], p)


@register_jitable
def disc_bits_within(x, y, h, ox, oy, radius, reach, p):
    """``disc_bits`` with the activation distance ``reach`` (units)."""
    dx = ox - x
    dy = oy - y
    d2 = dx * dx + dy * dy
    far = reach + radius
    if d2 > far * far:
        return 0
    d = math.sqrt(d2)
    if d <= radius:  # the sensors lie inside the disc (never after a cancelled move)
        return OBJECT_LEFT | OBJECT_RIGHT
    rel = wrap180(math.atan2(dx, dy) * RAD2DEG - h)
    bits = 0
    if _disc_reaches(rel, p[P_OL_A], p[P_OL_B], d, radius, reach):
        bits |= OBJECT_LEFT
    if _disc_reaches(rel, p[P_OR_A], p[P_OR_B], d, radius, reach):
        bits |= OBJECT_RIGHT
    return bits


@register_jitable
def box_distance2(x, y, x0, y0, x1, y1):
    """Squared distance from (x, y) to the axis-aligned box [x0, x1] × [y0, y1] (0 inside)."""
    dx = max(x0 - x, 0.0, x - x1)
    dy = max(y0 - y, 0.0, y - y1)
    return dx * dx + dy * dy


@register_jitable
def _ray_box_entry(x, y, bearing, x0, y0, x1, y1):
    """Distance along the ray from (x, y) at ``bearing`` (deg) to where it enters the box
    [x0, x1] × [y0, y1] (0 when it starts inside), +inf when it misses (slab method)."""
    r = bearing * DEG2RAD
    dirs = (math.sin(r), math.cos(r))
    starts = (x, y)
    lows = (x0, y0)
    highs = (x1, y1)
    lo = 0.0
    hi = math.inf
    for k in range(2):
        d = dirs[k]
        if d == 0.0:
            if starts[k] < lows[k] or starts[k] > highs[k]:
                return math.inf
            continue
        ta = (lows[k] - starts[k]) / d
        tb = (highs[k] - starts[k]) / d
        if ta > tb:
            ta, tb = tb, ta
        lo = max(lo, ta)
        hi = min(hi, tb)
    if lo > hi:
        return math.inf
    return lo


@register_jitable
def _point_in_view(x, y, h, a, b, qx, qy, reach):
    """Whether the point (qx, qy) lies within ``reach`` of (x, y) along a direction of the span
    [a, b] of relative bearings (heading ``h``)."""
    dx = qx - x
    dy = qy - y
    if dx * dx + dy * dy > reach * reach:
        return False
    rel = wrap180(math.atan2(dx, dy) * RAD2DEG - h)
    return _span_offset(rel, a, b) == 0.0


@register_jitable
def _box_in_span(x, y, h, a, b, x0, y0, x1, y1, reach):
    """Whether some point of the box [x0, x1] × [y0, y1] (not holding (x, y)) lies within
    ``reach`` along a direction of span [a, b] (narrower than 180°).

    The nearest such point is a vertex of the box cut by the span's cone, or the foot of the
    perpendicular on one of its edges: a corner of the box in view, the foot on a box edge in
    view, or where one of the span's two edge rays enters the box."""
    for edge in (a, b):
        if _ray_box_entry(x, y, wrap360(h + edge), x0, y0, x1, y1) <= reach:
            return True
    for qx in (x0, x1):
        for qy in (y0, y1):
            if _point_in_view(x, y, h, a, b, qx, qy, reach):
                return True
    if y0 <= y <= y1:
        for qx in (x0, x1):
            if _point_in_view(x, y, h, a, b, qx, y, reach):
                return True
    if x0 <= x <= x1:
        for qy in (y0, y1):
            if _point_in_view(x, y, h, a, b, x, qy, reach):
                return True
    return False


@register_jitable
def block_bits(x, y, h, x0, y0, x1, y1, reach, p):
    """Object-sensor bits that a block, the axis-aligned box [x0, x1] × [y0, y1] (an
    envelope's station, SPEC §9), activates at pose (x, y, h): as ``disc_bits``, a span is
    active if some point of the block lies within ``reach`` along a direction in the span."""
    d2 = box_distance2(x, y, x0, y0, x1, y1)
    if d2 == 0.0:  # the centre touches the block
        return OBJECT_LEFT | OBJECT_RIGHT
    if d2 > reach * reach:
        return 0
    bits = 0
    if _box_in_span(x, y, h, p[P_OL_A], p[P_OL_B], x0, y0, x1, y1, reach):
        bits |= OBJECT_LEFT
    if _box_in_span(x, y, h, p[P_OR_A], p[P_OR_B], x0, y0, x1, y1, reach):
        bits |= OBJECT_RIGHT
    return bits


@register_jitable
def _oval_segment2(au, av, bu, bv, a, b):
    """Least (u/a)² + (v/b)² over the segment from (au, av) to (bu, bv) (body frame)."""
    du = bu - au
    dv = bv - av
    qa = (du / a) ** 2 + (dv / b) ** 2
    t = 0.0
    if qa > 0.0:
        t = min(max(-(au * du / (a * a) + av * dv / (b * b)) / qa, 0.0), 1.0)
    u = au + t * du
    v = av + t * dv
    return (u / a) ** 2 + (v / b) ** 2


@register_jitable
def oval_box_gauge2(x, y, h, x0, y0, x1, y1, front, back, side):
    """How deep the box [x0, x1] × [y0, y1] reaches into a robot's oval footprint at pose
    (x, y, h): the least (u/a)² + (v/b)² over the box's points, (u, v) a point in the robot's
    frame (u ahead along heading ``h``, v to the side; units), a = ``front`` ahead of the
    centre and ``back`` behind it, b = ``side``. Below 1: the box overlaps the footprint (two
    half-ellipses joined at the centre); 0 when the centre lies in the box. The least lies on
    the box's boundary, so on one of its edges, whose pieces ahead of and behind the centre
    are each a quadratic in the edge's parameter."""
    if x0 <= x <= x1 and y0 <= y <= y1:
        return 0.0
    r = h * DEG2RAD
    fx = math.sin(r)
    fy = math.cos(r)
    xs = (x0, x1, x1, x0)
    ys = (y0, y0, y1, y1)
    best = math.inf
    for k in range(4):
        px = xs[k] - x
        py = ys[k] - y
        qx = xs[(k + 1) % 4] - x
        qy = ys[(k + 1) % 4] - y
        au = px * fx + py * fy
        av = px * fy - py * fx
        bu = qx * fx + qy * fy
        bv = qx * fy - qy * fx
        if au * bu < 0.0:  # the edge crosses the robot's lateral axis: split it there
            mv = av + au / (au - bu) * (bv - av)
            a_first = front if au > 0.0 else back
            a_second = back if au > 0.0 else front
            best = min(best, _oval_segment2(au, av, 0.0, mv, a_first, side),
                       _oval_segment2(0.0, mv, bu, bv, a_second, side))  # fmt: skip
        else:
            a = front if au + bu > 0.0 else back
            best = min(best, _oval_segment2(au, av, bu, bv, a, side))
    return best


@register_jitable
def block_stops(x, y, h, nx, ny, nh, x0, y0, x1, y1, radius, front, back, side):
    """Whether a move from pose (x, y, h) to (nx, ny, nh) is cancelled by the block [x0, x1] ×
    [y0, y1]. With ``front`` 0 the robot is a disc: the new centre lies closer than ``radius``
    to the block and closer than the old one (a robot placed overlapping it may back out,
    never go deeper). Otherwise its footprint is the oval of ``oval_box_gauge2`` (``front``,
    ``back``, ``side``; units): the block overlaps the new footprint deeper than the old one."""
    if front > 0.0:
        reach = max(front, back, side)
        if box_distance2(nx, ny, x0, y0, x1, y1) >= reach * reach:
            return False
        new = oval_box_gauge2(nx, ny, nh, x0, y0, x1, y1, front, back, side)
        return new < 1.0 and new < oval_box_gauge2(x, y, h, x0, y0, x1, y1, front, back, side)
    d2 = box_distance2(nx, ny, x0, y0, x1, y1)
    return d2 < radius * radius and d2 < box_distance2(x, y, x0, y0, x1, y1)


@register_jitable
def block_slide_end(x, y, nx, ny, x0, y0, x1, y1, friction):
    """End of a move from centre (x, y) to (nx, ny) that the block [x0, x1] × [y0, y1] stops,
    slid along it (``Envelope.station_blocking = "slide"``), arena frame, units. With n the
    unit normal from the block's point nearest (x, y) to (x, y) and d = (nx − x, ny − y): the
    component d·n < 0 into the block is dropped, and the tangential rest t = d − (d·n) n is
    shortened by ``friction`` × |d·n| (Coulomb friction of the body against the block; 0 when
    friction takes it all). Returns (x, y) + t·max(0, |t| − friction |d·n|) / |t|; (x, y)
    for a start on or in the block or a move straight into it; (nx, ny) for a move not into
    it (d·n ≥ 0)."""
    cx = min(max(x, x0), x1)
    cy = min(max(y, y0), y1)
    norm, ux, uy, dx, dy, dn = _contact(x, y, nx, ny, cx, cy)
    if norm == 0.0:
        return x, y
    if dn >= 0.0:
        return nx, ny
    tx = dx - dn * ux
    ty = dy - dn * uy
    t = math.sqrt(tx * tx + ty * ty)
    if t == 0.0:
        return x, y
    keep = max(0.0, t + friction * dn) / t
    return x + keep * tx, y + keep * ty


@register_jitable
def too_close(x, y, ox, oy, min_dist):
    """Whether centres (x, y) and (ox, oy) are closer than ``min_dist`` (SPEC §7 collision:
    two disc radii; exactly ``min_dist`` apart is allowed)."""
    dx = ox - x
    dy = oy - y
    return dx * dx + dy * dy < min_dist * min_dist


@register_jitable
def slide_end(x, y, nx, ny, ox, oy):
    """End of a move from centre (x, y) to (nx, ny) that the disc centred (ox, oy) blocks,
    under ``ColonySettings.blocking = "slide"``: the move keeps its component along the
    contact tangent (arena frame, units). With d = (nx − x, ny − y) and n = (x − ox, y − oy)
    / |…| (the unit normal from the other centre to this one at the move's start), returns
    (x, y) + d − (d·n) n when d·n < 0; else (nx, ny) (d does not point into the other disc),
    and (x, y) when the two centres coincide. The caller tests the end again
    (``too_close``): this does not say whether it is free."""
    norm, ux, uy, dx, dy, dn = _contact(x, y, nx, ny, ox, oy)
    if norm == 0.0:
        return x, y
    if dn >= 0.0:
        return nx, ny
    return x + (dx - dn * ux), y + (dy - dn * uy)


@register_jitable
def contact_yaw(x, y, h, ox, oy, yaw):
    """Heading change, degrees, of a robot at centre (x, y) with heading h (deg, clockwise
    from north) whose move the robot centred (ox, oy) blocks, under
    ``ColonySettings.contact_yaw_deg`` = ``yaw``: −yaw · sin b, b the bearing of (ox, oy)
    from the heading (clockwise): a turn away from the contact, ``yaw`` for a robot abeam,
    none for one dead ahead or astern; 0 when the centres coincide."""
    dx = ox - x
    dy = oy - y
    d = math.sqrt(dx * dx + dy * dy)
    if d == 0.0:
        return 0.0
    r = h * DEG2RAD
    return -yaw * ((dx * math.cos(r) - dy * math.sin(r)) / d)


@register_jitable
def _contact(x, y, nx, ny, ox, oy):
    """A move from (x, y) to (nx, ny) against a contact point (ox, oy): (|(x, y) − (ox, oy)|,
    the unit normal ux, uy from the contact to (x, y) (unnormalised when that distance is 0),
    the move dx, dy, and d·n)."""
    ux = x - ox
    uy = y - oy
    norm = math.sqrt(ux * ux + uy * uy)
    if norm != 0.0:
        ux = ux / norm
        uy = uy / norm
    dx = nx - x
    dy = ny - y
    return norm, ux, uy, dx, dy, dx * ux + dy * uy


@register_jitable
def source_lights(x, y, k, p):
    """Whether light source k lights the point (x, y): the direction from the source to the
    point lies within the cone of half-angle P_LIGHT_HALF around P_LIGHT_AXIS."""
    sx = p[P_LIGHTS + 2 * k]
    sy = p[P_LIGHTS + 2 * k + 1]
    bearing = math.atan2(x - sx, y - sy) * RAD2DEG
    return abs(wrap180(bearing - p[P_LIGHT_AXIS])) <= p[P_LIGHT_HALF]


@register_jitable
def light_bits(x, y, h, p):
    """Active light-sensor bits (LIGHT_LEFT | LIGHT_RIGHT): a sensor is active when a source
    that lights the robot lies within its span of relative bearings."""
    bits = 0
    for k in range(int(p[P_N_LIGHTS])):
        if not source_lights(x, y, k, p):
            continue
        sx = p[P_LIGHTS + 2 * k]
        sy = p[P_LIGHTS + 2 * k + 1]
        rel = wrap180(math.atan2(sx - x, sy - y) * RAD2DEG - h)
        if p[P_LL_A] <= rel <= p[P_LL_B]:
            bits |= LIGHT_LEFT
        if p[P_LR_A] <= rel <= p[P_LR_B]:
            bits |= LIGHT_RIGHT
    return bits


@register_jitable
def square_at(x, y, p):
    """Index i + grid_n·j of the square whose central contact zone holds (x, y), else −1."""
    size = p[P_SQUARE]
    n = int(p[P_GRID_N])
    i = int(math.floor(x / size))
    j = int(math.floor(y / size))
    if i < 0 or i >= n or j < 0 or j >= n:
        return -1
    half = p[P_CONTACT]
    if abs(x - (size * i + 0.5 * size)) <= half and abs(y - (size * j + 0.5 * size)) <= half:
        return i + n * j
    return -1


@register_jitable
def square_is_inner(index, p):
    """Whether square ``index`` is an inner square (1 ≤ i, j ≤ grid_n − 2)."""
    n = int(p[P_GRID_N])
    i = index % n
    j = index // n
    return 1 <= i <= n - 2 and 1 <= j <= n - 2


@register_jitable
def killed(x, y, p):
    """Whether (x, y) lies in the kill zone (closer than P_KILL to a wall)."""
    m = p[P_KILL]
    size = p[P_ARENA]
    return x < m or x > size - m or y < m or y > size - m


@register_jitable
def docked(x, y, h, p):
    """Docking rule: x ≥ dock_x_min, |y − station_y| ≤ half-width, heading within tolerance."""
    return (
        x >= p[P_DOCK_X]
        and abs(y - p[P_STATION_Y]) <= p[P_DOCK_YHW]
        and abs(wrap180(h - p[P_DOCK_H])) <= p[P_DOCK_HTOL]
    )


# ---------------------------------------------------------------------------------------
# Public wrappers over WorldSettings.
# ---------------------------------------------------------------------------------------


def apply_gait(
    x: float, y: float, h: float, F: float, T: float, dH: float
) -> tuple[float, float, float]:
    """Pose (x, y cm; h deg) after one gait cycle (F, T cm; dH deg) — SPEC §1."""
    return move(float(x), float(y), float(h), float(F), float(T), float(dH))


def light_sensors(
    x: float, y: float, h: float, world: WorldSettings = DEFAULT_WORLD
) -> tuple[bool, bool]:
    """(left, right) light sensors at pose (x, y cm; h deg)."""
    bits = light_bits(float(x), float(y), float(h), packed_tuple(world))
    return bool(bits & LIGHT_LEFT), bool(bits & LIGHT_RIGHT)


def object_sensors(
    x: float, y: float, h: float, world: WorldSettings = DEFAULT_WORLD
) -> tuple[bool, bool]:
    """(left, right) object sensors at pose (x, y cm; h deg): walls within range in span."""
    bits = object_bits(float(x), float(y), float(h), packed_tuple(world))
    return bool(bits & OBJECT_LEFT), bool(bits & OBJECT_RIGHT)


def square_index(x: float, y: float, world: WorldSettings = DEFAULT_WORLD) -> int:
    """Index i + grid_n·j (i column/x, j row/y) of the square reached at (x, y), else −1."""
    return int(square_at(float(x), float(y), packed_tuple(world)))


def is_inner(index: int, world: WorldSettings = DEFAULT_WORLD) -> bool:
    """Whether square ``index`` is one of the inner squares (64 on the 10 × 10 grid)."""
    return bool(square_is_inner(int(index), packed_tuple(world)))


def in_kill_zone(x: float, y: float, world: WorldSettings = DEFAULT_WORLD) -> bool:
    """Whether a robot centred at (x, y) is in the kill zone."""
    return bool(killed(float(x), float(y), packed_tuple(world)))


def is_docked(x: float, y: float, h: float, world: WorldSettings = DEFAULT_WORLD) -> bool:
    """Whether pose (x, y cm; h deg) satisfies the docking rule."""
    return bool(docked(float(x), float(y), float(h), packed_tuple(world)))


def lit(x: float, y: float, world: WorldSettings = DEFAULT_WORLD) -> tuple[bool, ...]:
    """For each light source, whether it lights (x, y). The dark area is where none does."""
    p = packed_tuple(world)
    return tuple(bool(source_lights(float(x), float(y), k, p)) for k in range(len(world.lights)))


__all__ = [
    "apply_gait",
    "block_bits",
    "block_slide_end",
    "block_stops",
    "oval_box_gauge2",
    "box_distance2",
    "contact_yaw",
    "disc_bits",
    "disc_bits_within",
    "docked",
    "in_kill_zone",
    "is_docked",
    "is_inner",
    "killed",
    "light_bits",
    "light_sensors",
    "lit",
    "move",
    "object_bits",
    "object_sensors",
    "pack_world",
    "packed_tuple",
    "square_at",
    "square_index",
    "square_is_inner",
    "slide_end",
    "too_close",
    "wall_bits",
    "wrap180",
    "wrap360",
]
